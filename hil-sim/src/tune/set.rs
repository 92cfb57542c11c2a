//! The Monte-Carlo set a tuning job evaluates gains on: scenarios drawn
//! around the robot (D91), a training part the optimiser sees and a
//! validation part on disjoint seeds that only reports.
//!
//! Scenario `i` of a part is built from its seed alone
//! ([`TuneSet::scenario`]), so any shard or thread builds the same one:
//! - the reference: the paper's curve from the paper's start (3.35 m off)
//!   when the robot's `limits.max_speed_mps` is at least
//!   [`PAPER_CURVE_MIN_SPEED_MPS`], else the mismatch sweep's 2 m circle at
//!   0.5 m/s from 0.1 m outside it ([`crate::sweep::base_scenario`]);
//! - the paper's Case 2 perturbations in the window 10-35 s: slip
//!   β ∈ (0, 0.2) rad/s, actuator fault ε ∈ (0.125, 0.25), lateral skid
//!   scale ∈ (0.025, 0.1) (the default 0.05 in the middle), a torque
//!   disturbance of (0.05, 0.15)× the robot's torque limit (the paper's
//!   1 N·m is 0.1× its 10 N·m; the upper end is
//!   [`TuneSet::disturbance_max_fraction`]);
//! - parameter uncertainty: the plant's mass ×(0.8, 1.2) and yaw inertia
//!   ×(0.6, 1.6) (log-uniform) against the controller's model, and, with
//!   `torque_scale_min` < 1, the torque limit ×(torque_scale_min, 1)
//!   (a weak battery or a derated bridge);
//! - the sensing preset: the set's presets in turn (i mod n);
//! - the validation part ends with [`TuneSet::figure8`] runs of the same
//!   draws on the figure-8 (issue 34, D167): a path unlike the training
//!   one (both turning directions, curvature through zero), then
//!   [`TuneSet::square`] runs on the square with quarter turns on the spot
//!   (D213: v and ω never both non-zero, each from rest).

use crate::montecarlo::run_seed;
use crate::rng::Rng;
use crate::scenario::{PerturbationPart, Robot, Scenario, Sensing, BETA_RANGE, EPS_RANGE};
use serde::{Deserialize, Serialize};

/// A robot whose speed limit is at least this runs the tuning set on the
/// paper's curve (the paper robot's 1.0 m/s); slower ones on the circle.
pub const PAPER_CURVE_MIN_SPEED_MPS: f32 = 1.0;
/// Range of the plant's mass scale.
pub const MASS_SCALE: (f64, f64) = (0.8, 1.2);
/// Range of the plant's yaw-inertia scale (log-uniform).
pub const INERTIA_SCALE: (f64, f64) = (0.6, 1.6);
/// Range of the lateral skid scale (paper: 1; the simulator's default 0.05).
pub const SKID_SCALE: (f64, f64) = (0.025, 0.1);
/// Default range of the disturbance amplitude as a fraction of the torque
/// limit (the upper end is [`TuneSet::disturbance_max_fraction`]).
pub const DISTURBANCE_FRACTION: (f64, f64) = (0.05, 0.15);

fn default_disturbance_max() -> f64 {
    DISTURBANCE_FRACTION.1
}
/// Run-index offset of the validation part: its seeds are
/// `run_seed(seed, VALIDATION_OFFSET + i)`, never a training index.
pub const VALIDATION_OFFSET: u64 = 1 << 40;

/// Which part of the set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// What the optimiser minimises.
    Training,
    /// Disjoint seeds, reported beside the training cost.
    Validation,
}

/// The Monte-Carlo set of a tuning job (stored in its shard files).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneSet {
    /// The robot being tuned (its model is the controllers').
    pub robot: Robot,
    /// Sensing presets, used in turn.
    pub sensing: Vec<Sensing>,
    /// Base seed.
    pub seed: u64,
    /// Training scenarios.
    pub training: usize,
    /// Validation scenarios.
    pub validation: usize,
    /// Smallest torque-limit scale drawn (1 = the robot's limit always).
    pub torque_scale_min: f64,
    /// Run length \[s\].
    pub duration_s: f64,
    /// Upper end of the disturbance amplitude drawn, as a fraction of the
    /// torque limit (the lower end is [`DISTURBANCE_FRACTION`]'s, 0.05):
    /// 0.15 by default; the paper's Case 2 puts 1 N·m on a 2 N·m robot,
    /// 0.5 (`--disturbance-max`).
    #[serde(default = "default_disturbance_max")]
    pub disturbance_max_fraction: f64,
    /// Validation runs on the figure-8 after the `validation` runs of the
    /// training path (D167; shard files without it have none).
    #[serde(default)]
    pub figure8: usize,
    /// Validation runs on the square with turns on the spot after the
    /// figure-8 runs (D213; shard files without it have none).
    #[serde(default)]
    pub square: usize,
}

/// The perturbation window of every scenario of the set \[s\]: the cost
/// is the tracking error inside it (D92).
pub const WINDOW_S: [f64; 2] = [10.0, 35.0];
/// Least length of the window a run must reach \[s\] (`--duration` at
/// least `WINDOW_S[0]` + this): a shorter run leaves the cost a few
/// samples, or none (issue 34: a 10 s job tuned to nothing and its gains
/// tracked worse on the device).
pub const MIN_WINDOW_S: f64 = 5.0;

/// Default number of figure-8 validation runs (`--validate-figure8`).
pub const DEFAULT_FIGURE8: usize = 4;
/// Default number of validation runs on the square with turns on the spot
/// (`--validate-square`): none, so far (D213: every controller and gain set
/// measured tracks it at 0.16-1.0 m, which would decide the validation
/// cost alone).
pub const DEFAULT_SQUARE: usize = 0;

/// The path of a validation run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValidationPath {
    /// The training path (the paper's curve or the circle).
    Training,
    /// The figure-8.
    Figure8,
    /// The square with turns on the spot.
    Square,
}

impl ValidationPath {
    /// Name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Training => "training path",
            Self::Figure8 => "figure-8",
            Self::Square => "square",
        }
    }
}

impl TuneSet {
    /// Refuses sets no scenario could be built from (no sensing preset,
    /// no scenario, a scale outside (0, 1]); checks the first scenario.
    pub fn validate(&self) -> Result<(), String> {
        if self.sensing.is_empty() {
            return Err("tuning set: at least one sensing preset".into());
        }
        if self.training == 0 || self.validation == 0 {
            return Err("tuning set: --train and --validate must be at least 1".into());
        }
        if !(self.torque_scale_min > 0.0 && self.torque_scale_min <= 1.0) {
            return Err(format!(
                "tuning set: --torque-scale-min must be in (0, 1], got {}",
                self.torque_scale_min
            ));
        }
        let lo = DISTURBANCE_FRACTION.0;
        if !(self.disturbance_max_fraction > lo && self.disturbance_max_fraction <= 1.0) {
            return Err(format!(
                "tuning set: --disturbance-max must be in ({lo}, 1] (a fraction of the torque limit), got {}",
                self.disturbance_max_fraction
            ));
        }
        let least_s = WINDOW_S[0] + MIN_WINDOW_S;
        if self.duration_s.is_nan() || self.duration_s < least_s {
            return Err(format!(
                "tuning set: --duration {} s: the cost is the tracking error in the perturbation window from {} s on, \
                 so a run must last at least {least_s} s ({MIN_WINDOW_S} s of window; the default is 35 s)",
                self.duration_s, WINDOW_S[0]
            ));
        }
        let s = self.scenario(Part::Training, 0);
        s.validate()?;
        crate::limits::check_scenario(&s)
    }

    /// Seed of scenario `i` of `part`.
    pub fn seed_of(&self, part: Part, i: u64) -> u64 {
        match part {
            Part::Training => run_seed(self.seed, i),
            Part::Validation => run_seed(self.seed, VALIDATION_OFFSET + i),
        }
    }

    /// Number of scenarios of `part`.
    pub fn len(&self, part: Part) -> usize {
        match part {
            Part::Training => self.training,
            Part::Validation => self.validation + self.figure8 + self.square,
        }
    }

    /// True when the reference is the paper's curve (else the circle).
    pub fn paper_curve(&self) -> bool {
        self.robot.limits.max_speed_mps >= PAPER_CURVE_MIN_SPEED_MPS
    }

    /// Scenario `i` of `part` (module doc).
    pub fn scenario(&self, part: Part, i: u64) -> Scenario {
        let seed = self.seed_of(part, i);
        let tau = f64::from(self.robot.limits.torque_nm);
        let mut s = if self.paper_curve() {
            Scenario::paper_case(2, seed, None, None).with_robots(Some(&self.robot), None)
        } else {
            crate::sweep::base_scenario(&self.robot, seed, self.duration_s)
        };
        s.name = format!(
            "tune-{}-{}{i}",
            self.robot.name,
            match part {
                Part::Training => "t",
                Part::Validation => "v",
            }
        );
        s.duration_s = self.duration_s;
        s.seed = seed;
        // Independent of the generator paper_case draws from.
        let mut r = Rng::new(seed ^ 0x7475_6e65);
        let mut within = |(lo, hi): (f64, f64)| lo + (hi - lo) * r.uniform();
        s.perturbations = PerturbationPart {
            window_s: WINDOW_S,
            beta: within(BETA_RANGE),
            eps: within(EPS_RANGE),
            skid_scale: within(SKID_SCALE),
            disturbance_nm: tau * within((DISTURBANCE_FRACTION.0, self.disturbance_max_fraction)),
            ..PerturbationPart::none()
        };
        s.plant.mass_scale = within(MASS_SCALE);
        s.plant.inertia_scale = within((INERTIA_SCALE.0.ln(), INERTIA_SCALE.1.ln())).exp();
        let scale = within((self.torque_scale_min, 1.0));
        s.plant.torque_limit_nm = (self.torque_scale_min < 1.0).then_some(tau * scale);
        s.sensing.preset = self.sensing[i as usize % self.sensing.len()];
        if part == Part::Validation {
            match self.path_of(i as usize) {
                ValidationPath::Training => {}
                ValidationPath::Figure8 => {
                    s.trajectory = crate::scenario::TrajectoryKind::Figure8;
                    s.initial_pose = [0.0, 0.0, std::f64::consts::FRAC_PI_4];
                    s.name = format!("{}-figure8", s.name);
                }
                ValidationPath::Square => {
                    s.trajectory = crate::scenario::TrajectoryKind::Square;
                    s.initial_pose = [0.0, 0.0, 0.0];
                    s.name = format!("{}-square", s.name);
                }
            }
        }
        s
    }

    /// The path of validation run `i`.
    pub fn path_of(&self, i: usize) -> ValidationPath {
        if i < self.validation {
            ValidationPath::Training
        } else if i < self.validation + self.figure8 {
            ValidationPath::Figure8
        } else {
            ValidationPath::Square
        }
    }

    /// Every scenario of `part`, in index order.
    pub fn scenarios(&self, part: Part) -> Vec<Scenario> {
        (0..self.len(part) as u64)
            .map(|i| self.scenario(part, i))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run that ends before the cost window has enough of it is refused
    /// with the option, the value and the least length (issue 34).
    #[test]
    fn a_run_shorter_than_the_cost_window_is_refused() {
        let mut set = set(Robot::paper());
        set.duration_s = 10.0;
        let e = set.validate().unwrap_err();
        assert!(
            e.contains("--duration 10 s") && e.contains("at least 15 s"),
            "{e}"
        );
        set.duration_s = 15.0;
        set.validate().unwrap();
    }

    fn set(robot: Robot) -> TuneSet {
        TuneSet {
            robot,
            sensing: vec![Sensing::Mocap, Sensing::Imu],
            seed: 1,
            training: 50,
            validation: 50,
            torque_scale_min: 0.5,
            duration_s: 40.0,
            disturbance_max_fraction: DISTURBANCE_FRACTION.1,
            figure8: 2,
            square: 0,
        }
    }

    #[test]
    fn a_disturbance_bound_outside_its_range_is_refused_by_name() {
        for bad in [0.05, 0.0, -0.1, 1.5, f64::NAN] {
            let s = TuneSet {
                disturbance_max_fraction: bad,
                ..set(Robot::paper())
            };
            let e = s.validate().unwrap_err();
            assert!(e.contains("--disturbance-max"), "{bad}: {e}");
        }
        let s = TuneSet {
            disturbance_max_fraction: 0.6,
            ..set(Robot::paper())
        };
        s.validate().unwrap();
        let tau = f64::from(Robot::paper().limits.torque_nm);
        let d: Vec<f64> = (0..200)
            .map(|i| s.scenario(Part::Training, i).perturbations.disturbance_nm / tau)
            .collect();
        assert!(d.iter().all(|&x| (0.05..0.6).contains(&x)));
        // Uniform on (0.05, 0.6): some draws above the default's 0.15.
        assert!(d.iter().filter(|&&x| x > 0.15).count() > 100);
    }

    #[test]
    fn validation_seeds_are_disjoint_from_training_seeds() {
        let s = set(Robot::paper());
        let train: std::collections::BTreeSet<u64> =
            (0..1000).map(|i| s.seed_of(Part::Training, i)).collect();
        assert_eq!(train.len(), 1000);
        for i in 0..1000 {
            assert!(!train.contains(&s.seed_of(Part::Validation, i)));
        }
    }

    #[test]
    fn draws_stay_in_their_ranges_and_presets_alternate() {
        let s = set(Robot::paper());
        s.validate().unwrap();
        for i in 0..50 {
            let c = s.scenario(Part::Validation, i);
            let p = &c.perturbations;
            assert!(p.beta > 0.0 && p.beta < 0.2);
            assert!(p.eps >= 0.125 && p.eps < 0.25);
            assert!((0.025..0.1).contains(&p.skid_scale));
            assert!((0.5..1.5).contains(&p.disturbance_nm));
            assert!((0.8..1.2).contains(&c.plant.mass_scale));
            assert!((0.6..1.6).contains(&c.plant.inertia_scale));
            let t = c.plant.torque_limit_nm.unwrap();
            assert!((5.0..=10.0).contains(&t));
            let want = [Sensing::Mocap, Sensing::Imu][i as usize % 2];
            assert_eq!(c.sensing.preset, want);
            assert_eq!(c, s.scenario(Part::Validation, i));
            c.validate().unwrap();
        }
    }

    #[test]
    fn validation_ends_with_the_square_after_the_figure8() {
        let s = TuneSet {
            square: 3,
            ..set(Robot::paper())
        };
        assert_eq!(s.len(Part::Validation), 55);
        let v = s.scenarios(Part::Validation);
        for (i, c) in v.iter().enumerate() {
            let want = if i < 50 {
                ValidationPath::Training
            } else if i < 52 {
                ValidationPath::Figure8
            } else {
                ValidationPath::Square
            };
            assert_eq!(s.path_of(i), want, "{i}");
            let square = c.trajectory == crate::scenario::TrajectoryKind::Square;
            assert_eq!(square, want == ValidationPath::Square, "{i}");
            c.validate().unwrap();
            crate::limits::check_scenario(c).unwrap();
        }
    }

    #[test]
    fn validation_ends_with_the_figure8_on_its_own_seeds() {
        let s = set(Robot::paper());
        assert_eq!(s.len(Part::Validation), 52);
        let v = s.scenarios(Part::Validation);
        for (i, c) in v.iter().enumerate() {
            let f8 = c.trajectory == crate::scenario::TrajectoryKind::Figure8;
            assert_eq!(f8, s.path_of(i) == ValidationPath::Figure8, "{i}");
            c.validate().unwrap();
            crate::limits::check_scenario(c).unwrap();
        }
        assert!(s
            .scenarios(Part::Training)
            .iter()
            .all(|c| c.trajectory != crate::scenario::TrajectoryKind::Figure8));
    }

    #[test]
    fn slow_robots_track_the_circle() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robots/tb6612-2kg.toml"
        ))
        .unwrap();
        let s = set(Robot::from_toml_str(&text).unwrap());
        assert!(!s.paper_curve());
        let c = s.scenario(Part::Training, 0);
        assert_eq!(c.trajectory, crate::scenario::TrajectoryKind::Circle);
        assert!(set(Robot::paper()).paper_curve());
        c.validate().unwrap();
    }
}
