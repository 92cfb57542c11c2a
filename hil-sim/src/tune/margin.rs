//! The mismatch margin of a set of gains (issue 34, D167): how far the
//! simulated robot may differ from the controller's model, one field at a
//! time and beyond the tuning set's draws (mass ×0.8-1.2, inertia
//! ×0.6-1.6), before a run stops or diverges.
//!
//! Each direction ([`DIRECTIONS`]) has levels of growing mismatch; level
//! j runs only when every level before it passed (every run of it ran to
//! the end without a stop), on [`MARGIN_RUNS`] validation scenarios of the
//! set (their draws: slip, fault, skid, disturbance, sensing; the plant's
//! mass and inertia set to the level's, the other fields the robot's).
//! The margin is the first level that failed (None: every level passed).

use super::cost::score;
use super::set::{Part, TuneSet};
use crate::scenario::Scenario;
use controller_core::{ControllerConfig, ControllerKind};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Validation scenarios each level runs (the first of the validation part:
/// one per sensing preset of the default set).
pub const MARGIN_RUNS: usize = 2;

/// The field a direction changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Field {
    /// Plant mass × level.
    Mass,
    /// Plant yaw inertia × level.
    Inertia,
    /// Both wheel radii × level.
    Radii,
    /// Track × level.
    Track,
    /// Wheel friction (Coulomb and viscous) × level; a robot whose file
    /// has none gets level × 5 % of its torque limit as Coulomb friction.
    Friction,
    /// Actuation delay \[s\] = level.
    Delay,
}

impl Field {
    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mass => "mass",
            Self::Inertia => "inertia",
            Self::Radii => "radii",
            Self::Track => "track",
            Self::Friction => "friction",
            Self::Delay => "delay",
        }
    }

    /// A level as printed (`x1.4`, `5 ms`).
    pub fn level_text(self, level: f64) -> String {
        match self {
            Self::Delay => format!("{:.0} ms", 1e3 * level),
            _ => format!("x{level}"),
        }
    }
}

/// The directions and their levels, mildest first: mass ±40 % and
/// inertia ×0.6-1.6 first (the acceptance's range), then beyond.
pub const DIRECTIONS: [(Field, [f64; 3]); 10] = [
    (Field::Mass, [1.4, 1.7, 2.0]),
    (Field::Mass, [0.6, 0.5, 0.4]),
    (Field::Inertia, [1.6, 2.0, 2.5]),
    (Field::Inertia, [0.6, 0.45, 0.3]),
    (Field::Radii, [1.03, 1.06, 1.1]),
    (Field::Radii, [0.97, 0.94, 0.9]),
    (Field::Track, [1.05, 1.1, 1.2]),
    (Field::Track, [0.95, 0.9, 0.8]),
    (Field::Friction, [2.0, 3.0, 4.0]),
    (Field::Delay, [0.002, 0.005, 0.01]),
];

/// One direction's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Margin {
    /// The field.
    pub field: Field,
    /// Its levels, mildest first.
    pub levels: Vec<f64>,
    /// The first level at which a run stopped or diverged (None: none).
    pub fails_at: Option<f64>,
    /// Runs at each level that ran (level index, stops of [`MARGIN_RUNS`]).
    pub stops: Vec<(usize, usize)>,
}

impl Margin {
    /// `x1.7` or `> x2.0`.
    pub fn text(&self) -> String {
        match self.fails_at {
            Some(l) => self.field.level_text(l),
            None => format!(
                ">{}",
                self.field.level_text(*self.levels.last().expect("levels"))
            ),
        }
    }
}

/// `scn` with the plant's `field` at `level`.
pub fn apply(mut scn: Scenario, field: Field, level: f64) -> Scenario {
    let r = scn.robot.clone();
    let table = |pairs: Vec<(&str, toml::Value)>| {
        Some(
            pairs
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect::<toml::Table>(),
        )
    };
    match field {
        Field::Mass => scn.plant.mass_scale = level,
        Field::Inertia => scn.plant.inertia_scale = level,
        Field::Radii => {
            let [a, b] = r.body.wheel_radius_m.map(|v| f64::from(v) * level);
            scn.plant.body = table(vec![(
                "wheel_radius_m",
                toml::Value::Array(vec![toml::Value::Float(a), toml::Value::Float(b)]),
            )]);
        }
        Field::Track => {
            // As the sweep's track case: an inertia near robot-file's bound
            // m·(track² + r²) is scaled down with the bound.
            let t = f64::from(r.body.track_m) * level;
            let rr = f64::from(r.mean_wheel_radius_m());
            let bound = |t: f64| f64::from(r.body.mass_kg) * (t * t + rr * rr);
            let i = f64::from(r.body.inertia_kgm2);
            let mut fields = vec![("track_m", toml::Value::Float(t))];
            if i > crate::sweep::TRACK_INERTIA_MARGIN * bound(t) {
                fields.push((
                    "inertia_kgm2",
                    toml::Value::Float(i * bound(t) / bound(f64::from(r.body.track_m))),
                ));
            }
            scn.plant.body = table(fields);
        }
        Field::Friction => {
            let c = r.motors.coulomb_friction_nm.map(f64::from);
            let v = r.motors.viscous_friction_nms_per_rad.map(f64::from);
            let (c, v) = if c[0] + c[1] > 0.0 {
                (c.map(|x| x * level), v.map(|x| x * level))
            } else {
                let coulomb = 0.05 * level * f64::from(r.limits.torque_nm);
                ([coulomb; 2], v)
            };
            scn.plant.motors = table(vec![
                (
                    "coulomb_friction_nm",
                    toml::Value::Array(c.map(toml::Value::Float).to_vec()),
                ),
                (
                    "viscous_friction_nms_per_rad",
                    toml::Value::Array(v.map(toml::Value::Float).to_vec()),
                ),
            ]);
        }
        Field::Delay => scn.plant.actuation_delay_s = level,
    }
    scn.plant.mass_scale = if field == Field::Mass { level } else { 1.0 };
    scn.plant.inertia_scale = if field == Field::Inertia { level } else { 1.0 };
    scn
}

/// The margins of `kind` with `make(scenario's configuration)` on `set`'s
/// first [`MARGIN_RUNS`] validation scenarios; `tick` once per run.
pub fn margins(
    set: &TuneSet,
    kind: ControllerKind,
    make: &(dyn Fn(&ControllerConfig) -> ControllerConfig + Sync),
    tick: &(dyn Fn() + Sync),
) -> Vec<Margin> {
    let n = MARGIN_RUNS.min(set.validation).max(1);
    let base: Vec<Scenario> = (0..n as u64)
        .map(|i| set.scenario(Part::Validation, i))
        .collect();
    let mut out: Vec<Margin> = DIRECTIONS
        .iter()
        .map(|(f, l)| Margin {
            field: *f,
            levels: l.to_vec(),
            fails_at: None,
            stops: Vec::new(),
        })
        .collect();
    for j in 0..3 {
        let live: Vec<usize> = (0..out.len())
            .filter(|&d| out[d].fails_at.is_none())
            .collect();
        let jobs: Vec<(usize, usize)> = live
            .iter()
            .flat_map(|&d| (0..n).map(move |s| (d, s)))
            .collect();
        let stopped: Vec<bool> = jobs
            .par_iter()
            .map(|&(d, s)| {
                let scn = apply(base[s].clone(), out[d].field, out[d].levels[j]);
                let r = score(&scn, make(&scn.controller_config(kind)));
                tick();
                r.stopped
            })
            .collect();
        for &d in &live {
            let stops = jobs
                .iter()
                .zip(&stopped)
                .filter(|((dd, _), s)| *dd == d && **s)
                .count();
            out[d].stops.push((j, stops));
            if stops > 0 {
                out[d].fails_at = Some(out[d].levels[j]);
            }
        }
    }
    out
}

/// Simulations [`margins`] runs at most for one set of gains.
pub fn max_simulations(set: &TuneSet) -> u64 {
    (DIRECTIONS.len() * 3 * MARGIN_RUNS.min(set.validation).max(1)) as u64
}
