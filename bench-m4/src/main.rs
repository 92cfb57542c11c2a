//! Instructions (QEMU) or cycles (board, feature `dwt`) per control step on
//! a Cortex-M4F, for the three controllers, the stages of the proposed one,
//! the reference sampling and the math routines. Prints a Markdown table
//! over semihosting and exits 0 (1 on a failed sanity check or a panic).
//!
//! The stages are the public `ControlLaw` functions that `Controller::step`
//! is made of, called here one at a time on a second state and checked bit
//! for bit against `Controller::step` at every step (see [`staged_step`]).
//!
//! Run: `cargo run --release` (QEMU mps2-an386, see .cargo/config.toml).
#![no_std]
#![no_main]
// `!(x <= limit)` is deliberate (NaN counts as out of range), as in controller.rs.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod tick;
mod timer;

use core::hint::black_box;
use core::panic::PanicInfo;

use controller_core::controller::{saturate, ControlLaw, ControllerState};
use controller_core::health::EstimatorHealth;
use controller_core::math;
use controller_core::pacer::{Pacer, PacingConfig};
use controller_core::trajectory::{PaperCurve, PaperHeading, Trajectory};
use controller_core::RobotParams;
use controller_core::{
    Controller, ControllerConfig, ControllerKind, Diagnostics, RefSample, StepInput, StepOutput,
};
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use sim_robot::world::{Actuation, Faults, IdealSensing, Instruments, Reading};
use sim_robot::{PerturbationProfile, PlantParams, World, WorldConfig};
use timer::Counter;

/// Control steps per controller: the paper's 40 s at 1 kHz.
const STEPS: u32 = 40_000;
/// Calls per math routine.
const MATH_CALLS: u32 = 2_000;

/// Accumulated counts of one timed item.
#[derive(Clone, Copy, Default)]
pub(crate) struct Stat {
    sum: u64,
    n: u32,
    max: u32,
}

impl Stat {
    #[inline(always)]
    pub(crate) fn add(&mut self, counts: u32) {
        self.sum += counts as u64;
        self.n += 1;
        self.max = self.max.max(counts);
    }
    fn mean(&self) -> f32 {
        self.sum as f32 / self.n.max(1) as f32
    }
}

/// Times one call of `f` (inputs must be black_boxed inside `f`).
#[inline(always)]
pub(crate) fn time<C: Counter, R>(c: &C, st: &mut Stat, f: impl FnOnce() -> R) -> R {
    let t0 = c.now();
    let r = black_box(f());
    let t1 = c.now();
    st.add(c.elapsed(t0, t1));
    r
}

/// Converts counts to the reported unit (instructions under QEMU, cycles with DWT).
struct Scale {
    per_count: f32,
    overhead: f32,
}

impl Scale {
    fn mean(&self, s: &Stat) -> f32 {
        (s.mean() - self.overhead) * self.per_count
    }
    fn max(&self, s: &Stat) -> f32 {
        (s.max as f32 - self.overhead) * self.per_count
    }
}

/// The paper's Case 2 perturbations: slip β = 0.1 rad/s, skid, a 1 N·m
/// disturbance and an actuator fault ε = 0.2 in [10 s, 35 s).
pub(crate) fn case2_profile() -> PerturbationProfile {
    PerturbationProfile {
        window_s: [10.0, 35.0],
        beta_radps: 0.1,
        fault_eps: 0.2,
        skid_scale: 0.05,
        disturbance_nm: 1.0,
        fault_eps_end: None,
    }
}

/// The simulated world that closes the loop (`sim_robot::World`, f64
/// through libm, soft-float on this core; not timed): the paper's plant,
/// one RK4 step per period, the paper's Case 2 perturbations, and ideal
/// sensing as hil-sim's paper runs have it (the exact pose of G, the wheel
/// rates from the exact wheel-angle change over the period into η by
/// eq. (3), torques applied exactly). The simulator's default start;
/// the reference starts at (4, 3).
pub(crate) fn case2_world(robot: &RobotParams, dt: f64, instruments: Instruments) -> World {
    World::new(&WorldConfig {
        plant: PlantParams::from_robot(robot, 1.0, 1.0),
        perturbations: case2_profile(),
        initial_pose: [2.5, 0.0, 0.0],
        period_s: dt,
        substeps: 1,
        seed: 0,
        instruments,
        faults: Faults::NONE,
    })
    .unwrap_or_else(|_| fail("world config"))
}

/// The controller's input from an ideal world's reading.
fn ideal_input(robot: &RobotParams, reference: RefSample, reading: &Reading) -> StepInput {
    let Some(m) = reading.ideal else {
        fail("not an ideal world");
    };
    StepInput {
        reference,
        pose: m.pose,
        eta: robot.eta_from_wheel_rates(m.wheel_rate_radps),
    }
}

/// Per-stage counts of the proposed controller's step.
#[derive(Default)]
struct StageStats {
    check_input: Stat,
    kinematic: Stat,
    dynamic: Stat,
    saturate: Stat,
    advance: Stat,
    output: Stat,
}

/// What [`staged_step`] computed, to compare bit for bit with `Controller::step`.
struct StagedOutput {
    torque_nm: [f32; 2],
    diag: Diagnostics,
    state_is_finite: bool,
}

/// One control period made of the public [`ControlLaw`] stages, in the order
/// `Controller::step` calls them, each timed on its own (inputs black-boxed
/// inside the timed region, outputs black-boxed by `time`). This is the code
/// the step runs, not a copy of it: `run_controller` fails unless the torque,
/// the diagnostics and the state equal `Controller::step`'s bit for bit.
#[inline(never)]
fn staged_step<C: Counter>(
    c: &C,
    st: &mut StageStats,
    law: &ControlLaw,
    state: &mut ControllerState,
    input: &StepInput,
) -> StagedOutput {
    let checked = time(c, &mut st.check_input, || law.check_input(black_box(input)));
    if checked.is_err() {
        fail("staged: input rejected");
    }
    let kin = time(c, &mut st.kinematic, || {
        law.kinematic(black_box(&mut state.fault_observer), black_box(input))
    });
    let dynamic = time(c, &mut st.dynamic, || {
        law.dynamic(black_box(&*state), black_box(input.eta), black_box(&kin))
    });
    let limit_nm = law.config().torque_limit_nm;
    let applied = time(c, &mut st.saturate, || {
        saturate(black_box(dynamic.torque_request_nm), black_box(limit_nm))
    });
    time(c, &mut st.advance, || {
        law.advance(
            black_box(&mut *state),
            black_box(input.eta),
            black_box(&dynamic),
            black_box(&applied),
        )
    });
    let (diag, state_is_finite) = time(c, &mut st.output, || {
        let state = black_box(&*state);
        let diag = law.diagnostics(
            state,
            black_box(&kin),
            black_box(&dynamic),
            black_box(&applied),
        );
        (diag, state.is_finite())
    });
    StagedOutput {
        torque_nm: applied.torque_nm,
        diag,
        state_is_finite,
    }
}

pub(crate) fn fail(what: &str) -> ! {
    hprintln!("FAIL: {}", what);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::nop();
    }
}

struct RunResult {
    reference: Stat,
    step: Stat,
    /// `Pacer::update` (governor + health machine) after the step.
    pacer: Stat,
    stages: StageStats,
    final_error: [f32; 3],
    max_pos_error_after_10s: f32,
}

#[inline(never)]
fn run_controller<C: Counter>(c: &C, kind: ControllerKind) -> RunResult {
    let cfg = ControllerConfig::paper(kind);
    let mut ctrl = Controller::new(cfg).unwrap_or_else(|_| fail("config"));
    // The stages run on their own copy of the parameters and state.
    let law = ctrl.law().clone();
    let mut staged_state = law.initial_state();
    let traj = PaperCurve::paper(PaperHeading::SignedSmooth);
    let mut world = case2_world(
        &cfg.robot,
        cfg.period_s as f64,
        Instruments::Ideal(IdealSensing {
            position_noise_m: 0.0,
            heading_noise_rad: 0.0,
            rate_period_s: cfg.period_s as f64,
        }),
    );
    let mut res = RunResult {
        reference: Stat::default(),
        step: Stat::default(),
        pacer: Stat::default(),
        stages: StageStats::default(),
        final_error: [0.0; 3],
        max_pos_error_after_10s: 0.0,
    };
    // The governor and health machine as the runtime runs them after each
    // step (timed on the step's diagnostics; the reference here stays the
    // nominal one, so the closed loop is the paper's).
    let pacer = Pacer::new(PacingConfig::on(), &cfg).unwrap_or_else(|_| fail("pacing config"));
    let mut pace = pacer.initial_state();
    let dt = cfg.period_s;
    for k in 0..STEPS {
        let t = k as f32 * dt;
        let r = time(c, &mut res.reference, || traj.sample(black_box(t)));
        let reading = world.sense(k as f64 * dt as f64);
        let input = ideal_input(&cfg.robot, r, &reading);
        let out: StepOutput = time(c, &mut res.step, || ctrl.step(black_box(&input)));
        if out.diag.fault.is_some() {
            fail("controller rejected a step");
        }
        let rep = time(c, &mut res.pacer, || {
            pacer.update(
                black_box(&mut pace),
                black_box(&out.diag),
                black_box(input.eta),
                EstimatorHealth::Ok,
            )
        });
        if !(rep.scale >= 0.0 && rep.scale <= 1.0) {
            fail("time scale out of [0, 1]");
        }
        if kind == ControllerKind::Proposed {
            // The stages, run one by one, must give exactly what the step gave.
            let so = staged_step(c, &mut res.stages, &law, &mut staged_state, &input);
            let bits = |a: [f32; 2]| a.map(f32::to_bits);
            if bits(so.torque_nm) != bits(out.torque_nm)
                || so.diag != out.diag
                || !so.state_is_finite
                || staged_state != *ctrl.state()
            {
                fail("the stages run one by one differ from Controller::step");
            }
        }
        let e = out.diag.error;
        if t >= 10.0 {
            let pe = math::sqrt(e[0] * e[0] + e[1] * e[1]);
            res.max_pos_error_after_10s = res.max_pos_error_after_10s.max(pe);
        }
        res.final_error = e;
        let torque = Actuation::Torque(out.torque_nm.map(f64::from));
        if world.advance(torque, dt as f64).is_err() {
            fail("plant diverged");
        }
    }
    res
}

/// Mean counts per call of `f` over `n` inputs spread over [lo, hi].
#[inline(never)]
fn bench1<C: Counter, R>(c: &C, lo: f32, hi: f32, f: impl Fn(f32) -> R) -> u32 {
    let step = (hi - lo) / MATH_CALLS as f32;
    let t0 = c.now();
    let mut x = lo;
    for _ in 0..MATH_CALLS {
        black_box(f(black_box(x)));
        x += step;
    }
    let t1 = c.now();
    c.elapsed(t0, t1)
}

/// Max |f − g| over the same inputs as [`bench1`].
fn err1(lo: f32, hi: f32, f: impl Fn(f32) -> f32, g: impl Fn(f32) -> f32) -> f32 {
    let step = (hi - lo) / MATH_CALLS as f32;
    let mut x = lo;
    let mut e = 0.0f32;
    for _ in 0..MATH_CALLS {
        e = e.max((f(x) - g(x)).abs());
        x += step;
    }
    e
}

struct MathRow {
    name: &'static str,
    range: &'static str,
    libm: (u32, f32),
    micromath: Option<(u32, f32)>,
    fast: (u32, f32),
}

#[inline(never)]
fn math_rows<C: Counter>(c: &C) -> [MathRow; 9] {
    use controller_core::math::fast;
    use micromath::F32;
    let pi = core::f32::consts::PI;
    macro_rules! row {
        ($name:expr, $range:expr, $lo:expr, $hi:expr, $libm:expr, $mm:expr, $fast:expr) => {{
            let (lo, hi) = ($lo, $hi);
            MathRow {
                name: $name,
                range: $range,
                libm: (bench1(c, lo, hi, $libm), 0.0),
                micromath: {
                    let mm: Option<fn(f32) -> f32> = $mm;
                    mm.map(|m| (bench1(c, lo, hi, m), err1(lo, hi, m, $libm)))
                },
                fast: (bench1(c, lo, hi, $fast), err1(lo, hi, $fast, $libm)),
            }
        }};
    }
    let none: Option<fn(f32) -> f32> = None;
    let sc_err = |f: fn(f32) -> (f32, f32)| {
        err1(-pi, pi, |x| f(x).0, libm::sinf).max(err1(-pi, pi, |x| f(x).1, libm::cosf))
    };
    let mm_sc: fn(f32) -> (f32, f32) = |x| {
        let (s, c) = F32(x).sin_cos();
        (s.0, c.0)
    };
    let atan2_of = |x: f32| (x, 0.5 - 0.7 * x); // crosses quadrants for x in [-2, 2]
    [
        row!(
            "sin",
            "[-π, π]",
            -pi,
            pi,
            libm::sinf,
            Some(|x| F32(x).sin().0),
            fast::sin
        ),
        row!(
            "cos",
            "[-π, π]",
            -pi,
            pi,
            libm::cosf,
            Some(|x| F32(x).cos().0),
            fast::cos
        ),
        MathRow {
            name: "sin_cos",
            range: "[-π, π]",
            libm: (bench1(c, -pi, pi, libm::sincosf), 0.0),
            micromath: Some((bench1(c, -pi, pi, mm_sc), sc_err(mm_sc))),
            fast: (bench1(c, -pi, pi, fast::sin_cos), sc_err(fast::sin_cos)),
        },
        row!(
            "sin (large arg)",
            "[-100, 100]",
            -100.0,
            100.0,
            libm::sinf,
            Some(|x| F32(x).sin().0),
            fast::sin
        ),
        row!(
            "atan2",
            "y∈[-2,2], x=0.5−0.7y",
            -2.0,
            2.0,
            |v| {
                let (y, x) = atan2_of(v);
                libm::atan2f(y, x)
            },
            Some(|v| {
                let (y, x) = (v, 0.5 - 0.7 * v);
                F32(y).atan2(F32(x)).0
            }),
            |v| {
                let (y, x) = atan2_of(v);
                fast::atan2(y, x)
            }
        ),
        row!("tanh", "[-3, 3]", -3.0, 3.0, libm::tanhf, none, fast::tanh),
        row!(
            "sqrt",
            "[0.01, 10]",
            0.01,
            10.0,
            libm::sqrtf,
            Some(|x| F32(x).sqrt().0),
            fast::sqrt
        ),
        row!(
            "powf(x, 0.01)",
            "[0.1, 2]",
            0.1,
            2.0,
            |x| libm::powf(x, 0.01),
            Some(|x| F32(x).powf(F32(0.01)).0),
            |x| fast::powf(x, 0.01)
        ),
        row!(
            "floor",
            "[-10, 10]",
            -10.0,
            10.0,
            libm::floorf,
            Some(|x| F32(x).floor().0),
            fast::floor
        ),
    ]
}

#[cfg(not(feature = "dwt"))]
fn counter() -> timer::SysTickCounter {
    let p = cortex_m::Peripherals::take().unwrap_or_else(|| fail("peripherals"));
    timer::SysTickCounter::start(p.SYST)
}

#[cfg(feature = "dwt")]
fn counter() -> timer::DwtCounter {
    let p = cortex_m::Peripherals::take().unwrap_or_else(|| fail("peripherals"));
    timer::DwtCounter::start(p.DCB, p.DWT)
}

#[entry]
fn main() -> ! {
    let c = counter();
    // Calibration: 2·N instructions.
    const CAL: u32 = 1_000_000;
    let cal = timer::calibrate(&c, CAL);
    let per_count = if cfg!(feature = "dwt") {
        1.0
    } else {
        2.0 * CAL as f32 / cal as f32
    };
    // Overhead of `time` around nothing.
    let mut ovh = Stat::default();
    for _ in 0..10_000 {
        time(&c, &mut ovh, || black_box(0u32));
    }
    let scale = Scale {
        per_count,
        overhead: ovh.mean(),
    };
    let unit = if cfg!(feature = "dwt") {
        "cycles"
    } else {
        "instructions"
    };
    hprintln!("# bench-m4: {} per call on a Cortex-M4F", unit);
    hprintln!(
        "counter: {}; calibration: {} counts for {} two-instruction loop iterations -> {} {} per count; timing overhead {} counts subtracted",
        <timer::SysTickCounter as Counter>::UNIT,
        cal,
        CAL,
        per_count,
        unit,
        ovh.mean()
    );
    hprintln!(
        "math: {}",
        match math::selected() {
            math::MathImpl::Fast => "fast (controller-core default)",
            math::MathImpl::Accurate => "accurate (libm, feature accurate-math)",
        }
    );
    hprintln!("");
    hprintln!("| item | calls | mean {} | max {} |", unit, unit);
    hprintln!("|---|---:|---:|---:|");
    let mut proposed_mean = 0.0;
    let mut proposed_max = 0.0;
    for kind in ControllerKind::ALL {
        let r = run_controller(&c, kind);
        if !(r.max_pos_error_after_10s < 0.5) {
            hprintln!(
                "{}: max position error after 10 s {} m",
                kind.name(),
                r.max_pos_error_after_10s
            );
            fail("closed loop did not track");
        }
        let row = |name: &str, s: &Stat| {
            hprintln!(
                "| {} | {} | {:.0} | {:.0} |",
                name,
                s.n,
                scale.mean(s),
                scale.max(s)
            );
        };
        if kind == ControllerKind::Smc {
            row("reference sample (PaperCurve SignedSmooth)", &r.reference);
        }
        match kind {
            ControllerKind::Smc => row("SMC step", &r.step),
            ControllerKind::Asmc => row("ASMC step", &r.step),
            ControllerKind::Proposed => {
                row("**Proposed step**", &r.step);
                row(
                    "  + `Pacer::update` (governor + health machine, per tick)",
                    &r.pacer,
                );
                let stages = [
                    ("  stage 1: `check_input`", &r.stages.check_input),
                    (
                        "  stage 2: `kinematic` (e, F̂, η_c, η̇_c: eqs. 8, 13, 14)",
                        &r.stages.kinematic,
                    ),
                    (
                        "  stage 3: `dynamic` (s, τ request: eqs. 20, 24)",
                        &r.stages.dynamic,
                    ),
                    ("  stage 4: `saturate` (D14)", &r.stages.saturate),
                    (
                        "  stage 5: `advance` (∫e_η, ρ̂, fal-ESO: eqs. 18-19)",
                        &r.stages.advance,
                    ),
                    (
                        "  stage 6: `diagnostics` + `ControllerState::is_finite`",
                        &r.stages.output,
                    ),
                ];
                let mut sum = 0.0;
                for (name, s) in stages {
                    row(name, s);
                    sum += scale.mean(s);
                }
                hprintln!("|  stages sum | | {:.0} | |", sum);
                proposed_mean = scale.mean(&r.step);
                proposed_max = scale.max(&r.step);
            }
        }
        hprintln!(
            "<!-- {}: final error [{}, {}, {}], max |e_xy| after 10 s {} m -->",
            kind.name(),
            r.final_error[0],
            r.final_error[1],
            r.final_error[2],
            r.max_pos_error_after_10s
        );
    }
    // The whole firmware tick with the estimator (module `tick`).
    hprintln!("");
    hprintln!(
        "| firmware tick, proposed (`LoopTimer::tick` + `ControlLoop::tick`) | calls | mean {} | max {} |",
        unit,
        unit
    );
    hprintln!("|---|---:|---:|---:|");
    let mut typical_mean = 0.0f32;
    let mut typical_max = 0.0f32;
    let mut correction_max = 0.0f32;
    for (name, source) in [
        ("mocap (100 Hz, 10 ms)", sim_robot::sensors::PRESET_MOCAP),
        (
            "UWB at maximal latency (10 Hz, 250 ms)",
            tick::UWB_MAX_LATENCY,
        ),
    ] {
        let r = tick::run_tick(&c, source);
        if !(r.max_pos_error_after_10s < 0.5) || r.accepted < 100 {
            hprintln!(
                "{}: max position error after 10 s {} m, {} poses accepted",
                name,
                r.max_pos_error_after_10s,
                r.accepted
            );
            fail("tick: closed loop did not track or took no poses");
        }
        let row = |what: &str, s: &Stat| {
            if s.n == 0 {
                hprintln!("| {}: {} | 0 | — | — |", name, what);
                return;
            }
            hprintln!(
                "| {}: {} | {} | {:.0} | {:.0} |",
                name,
                what,
                s.n,
                scale.mean(s),
                scale.max(s)
            );
        };
        row("**every tick**", &r.tick_all);
        row(
            "**typical tick** (no measurement, no re-propagation)",
            &r.tick_plain,
        );
        row(
            "**tick with a correction** (update + ≤ 24 ticks re-propagated)",
            &r.tick_correction,
        );
        row(
            "**tick continuing a re-propagation** (≤ 24 ticks)",
            &r.tick_resume,
        );
        row("  `PoseEstimator::predict` alone", &r.predict);
        row(
            "  `PoseEstimator::resume` alone (a pending slice)",
            &r.resume,
        );
        row(
            "  `PoseEstimator::correct_within` alone (≤ 24 ticks now)",
            &r.correct,
        );
        row(
            "  `PoseEstimator::correct` (whole re-propagation at once)",
            &r.correct_whole,
        );
        hprintln!(
            "<!-- {}: {} poses accepted, largest latency {} ticks, max |e_xy| after 10 s {} m -->",
            name,
            r.accepted,
            r.max_latency_ticks,
            r.max_pos_error_after_10s
        );
        typical_mean = typical_mean.max(scale.mean(&r.tick_plain));
        typical_max = typical_max.max(scale.max(&r.tick_plain));
        correction_max = correction_max
            .max(scale.max(&r.tick_correction))
            .max(scale.max(&r.tick_resume));
    }
    hprintln!("");
    hprintln!(
        "| math routine | inputs | libm {} | micromath {} (max err vs libm) | fast {} (max err vs libm) |",
        unit,
        unit,
        unit
    );
    hprintln!("|---|---|---:|---:|---:|");
    let base = bench1(&c, 0.0, 1.0, |x| x) as f32;
    let per_call = |counts: u32| (counts as f32 - base) * per_count / MATH_CALLS as f32;
    for r in math_rows(&c) {
        match r.micromath {
            Some((mc, me)) => hprintln!(
                "| {} | {} | {:.0} | {:.0} ({:.1e}) | {:.0} ({:.1e}) |",
                r.name,
                r.range,
                per_call(r.libm.0),
                per_call(mc),
                me,
                per_call(r.fast.0),
                r.fast.1
            ),
            None => hprintln!(
                "| {} | {} | {:.0} | — | {:.0} ({:.1e}) |",
                r.name,
                r.range,
                per_call(r.libm.0),
                per_call(r.fast.0),
                r.fast.1
            ),
        }
    }
    hprintln!("");
    hprintln!(
        "RESULT proposed_step_mean={:.0} proposed_step_max={:.0} tick_typical_mean={:.0} tick_typical_max={:.0} tick_correction_max={:.0} unit={}",
        proposed_mean,
        proposed_max,
        typical_mean,
        typical_max,
        correction_max,
        unit
    );
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::nop();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::nop();
    }
}
