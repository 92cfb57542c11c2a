//! The H-bridge behind the pins, per bridge mode (the firmware's
//! `firmware/src/motors.rs`): from the input waveforms of one motor over a
//! PWM period to the mean armature voltage the bridge applies, as a
//! fraction of the supply.
//!
//! An H-bridge with inputs (A, B) drives forward when exactly A is on,
//! reverse when exactly B is on, brakes (both low-side or both high-side
//! switches closed: zero volts on the winding) or coasts (every switch
//! open) otherwise, as each mode's datasheet truth table says:
//!
//! | mode | forward | reverse | brake | coast |
//! |---|---|---|---|---|
//! | PwmDir (DRV8874 PH/EN, MD10C) | EN, PWM high, DIR low | EN, PWM high, DIR high | EN, PWM low | ENABLE low |
//! | TwoPwm (DRV8871, BTS7960) | IN1 high, IN2 low | IN1 low, IN2 high | both high | both low, or ENABLE (BTS7960 INH) low |
//! | PwmIn1In2 (TB6612FNG) | STBY, IN1 = 1, IN2 = 0, PWM high | STBY, 01, PWM high | IN1 = IN2 = 1, or PWM low with 10/01 | IN1 = IN2 = 0, or STBY low |
//!
//! The mean voltage is (time forward − time reverse) / period: drive/brake
//! (slow decay) gives ±duty × V_supply, what the motor model assumes. A
//! period that coasts throughout is reported as coasting (no torque); a
//! period mixing coast with drive is counted as brake for its coast part
//! (the current then freewheels through the diodes; not modelled).

pub use controller_core::runtime::BridgeMode;

use crate::periph::timer::Wave;

/// One input's high interval `[from, to)` in a period of `period` counts
/// (a level spans the whole period or none of it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interval {
    /// First count high.
    pub from: u32,
    /// One past the last count high.
    pub to: u32,
}

impl Interval {
    fn len(self) -> u32 {
        self.to.saturating_sub(self.from)
    }

    fn overlap(self, o: Self) -> u32 {
        self.to.min(o.to).saturating_sub(self.from.max(o.from))
    }
}

/// A waveform as an interval of `period` counts: released pins read low
/// (the board's pull-downs).
pub fn interval(w: Wave, period: u32) -> Interval {
    match w {
        Wave::Released | Wave::Level(false) => Interval { from: 0, to: 0 },
        Wave::Level(true) => Interval {
            from: 0,
            to: period,
        },
        Wave::Pwm { from, to, .. } => Interval { from, to },
    }
}

/// The common period of a motor's waveforms (one timer, so PWM inputs
/// share it; 1 when every input is a level).
pub fn period(waves: &[Wave]) -> u32 {
    waves
        .iter()
        .map(|w| match w {
            Wave::Pwm { period, .. } => *period,
            _ => 1,
        })
        .max()
        .unwrap_or(1)
}

/// Two-input bridge (IN1 = `a`, IN2 = `b`): the mean armature voltage
/// fraction, `None` when it coasts the whole period.
pub fn two_input(a: Wave, b: Wave) -> Option<f64> {
    let p = period(&[a, b]);
    let (a, b) = (interval(a, p), interval(b, p));
    let both = a.overlap(b);
    let fwd = a.len() - both;
    let rev = b.len() - both;
    let on = a.len() + b.len() - both;
    if on == 0 {
        return None; // both low throughout: coast
    }
    Some((fwd as f64 - rev as f64) / p as f64)
}

/// What one motor's bridge applies in `mode`: `pwm` the PWM / IN1 pin's
/// waveform (PA8 / PA9), `second` the second input (DIR in PwmDir, IN2 in
/// TwoPwm, IN1 in PwmIn1In2), `third` PwmIn1In2's IN2, `enable` the shared
/// ENABLE / STBY / INH line.
pub fn armature(
    mode: BridgeMode,
    pwm: Wave,
    second: Wave,
    third: Wave,
    enable: bool,
) -> Option<f64> {
    if !enable {
        return None;
    }
    let p = period(&[pwm, second, third]);
    let duty = interval(pwm, p).len() as f64 / p as f64;
    let level = |w: Wave| interval(w, p).len() * 2 > p;
    match mode {
        BridgeMode::PwmDir => Some(if level(second) { -duty } else { duty }),
        BridgeMode::TwoPwm => two_input(pwm, second),
        BridgeMode::PwmIn1In2 => match (level(second), level(third)) {
            (true, false) => Some(duty),
            (false, true) => Some(-duty),
            (true, true) => Some(0.0),
            (false, false) => None,
        },
    }
}

/// Bridge states shorter than this are transients \[ps\]: the states
/// between the stores of one update of the motor outputs (CCR, CCER, the
/// GPIO lines; a few tens of instructions, < 0.5 µs at CPI 1), unless an
/// interrupt lands between them.
pub const TRANSIENT_PS: u128 = 2_000_000;

/// Tolerance of [`TransientWatch`] (fraction of the supply).
pub const TRANSIENT_TOL: f64 = 0.01;

/// A run of transient states that drove a wheel harder than the stable
/// states on both sides of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transient {
    /// Wheel (0 right, 1 left).
    pub wheel: usize,
    /// The largest armature fraction during the run (signed).
    pub armature: f64,
    /// The stable states' fractions before and after it.
    pub before: f64,
    /// See `before`.
    pub after: f64,
    /// When the run began and how long it lasted \[ps\].
    pub at_ps: u128,
    /// See `at_ps`.
    pub len_ps: u128,
}

/// Watches the sequence of bridge states (each wheel's armature fraction,
/// coast = 0) for transients: states lasting less than [`TRANSIENT_PS`]
/// whose magnitude exceeds both the stable state before and the one after
/// them by more than [`TRANSIENT_TOL`]. Such a state is an ordering defect
/// of the writes (the new duty with the old direction lines, e.g.): on the
/// chip it lasts as long as the gap between two stores, or an interrupt.
#[derive(Clone, Debug, Default)]
pub struct TransientWatch {
    /// The state being watched, since when.
    current: Option<([f64; 2], u128)>,
    /// The last stable state.
    stable: [f64; 2],
    /// The open run of transients: its start and each wheel's largest
    /// magnitude (signed value kept).
    run: Option<(u128, [f64; 2])>,
}

impl TransientWatch {
    /// The bridge changed to `state` at `now_ps`; returns the transients
    /// the state just left closes (at most one per wheel).
    pub fn change(&mut self, now_ps: u128, state: [f64; 2]) -> Vec<Transient> {
        let mut out = Vec::new();
        let Some((left, since)) = self.current.replace((state, now_ps)) else {
            self.stable = state;
            return out;
        };
        if now_ps - since < TRANSIENT_PS {
            let (_, peak) = self.run.get_or_insert((since, [0.0; 2]));
            for i in 0..2 {
                if left[i].abs() > peak[i].abs() {
                    peak[i] = left[i];
                }
            }
            return out;
        }
        if let Some((start, peak)) = self.run.take() {
            for i in 0..2 {
                let bound = self.stable[i].abs().max(left[i].abs()) + TRANSIENT_TOL;
                if peak[i].abs() > bound {
                    out.push(Transient {
                        wheel: i,
                        armature: peak[i],
                        before: self.stable[i],
                        after: left[i],
                        at_ps: start,
                        len_ps: since - start,
                    });
                }
            }
        }
        self.stable = left;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: u32 = 8400;

    fn pwm(from: u32, to: u32) -> Wave {
        Wave::Pwm {
            from,
            to,
            period: P,
        }
    }

    /// TwoPwm as the firmware maps it: forward duty d = IN1 high, IN2 low
    /// for d (CCR = full − d, IN2 = OCxREF high for CNT < CCR): +d; reverse
    /// mirrored: −d; both high: brake 0; both low: coast.
    #[test]
    fn two_pwm_slow_decay_gives_plus_minus_duty() {
        let d = 840; // 10 %
        let fwd = two_input(Wave::Level(true), pwm(0, P - d)).unwrap();
        assert!((fwd - 0.1).abs() < 1e-9, "{fwd}");
        let rev = two_input(pwm(0, P - d), Wave::Level(true)).unwrap();
        assert!((rev + 0.1).abs() < 1e-9, "{rev}");
        assert_eq!(two_input(Wave::Level(true), Wave::Level(true)), Some(0.0));
        assert_eq!(two_input(Wave::Level(false), Wave::Level(false)), None);
    }

    /// Issue 18's lurch, the naive two-PWM mapping (IN1 = duty PWM, IN2 =
    /// the direction level): a small reverse command (10 %) applies 90 %
    /// of the supply in reverse; the firmware's mapping applies 10 %.
    #[test]
    fn naive_two_pwm_reverse_lurches() {
        let d = 840;
        let naive = two_input(pwm(0, d), Wave::Level(true)).unwrap();
        assert!((naive + 0.9).abs() < 1e-9, "{naive}");
    }

    /// PWM + DIR and PWM + IN1 + IN2: ±duty; TB6612 brake and coast; the
    /// enable line low coasts every mode.
    #[test]
    fn pwm_dir_and_in1_in2() {
        let d = pwm(0, 2100);
        let (lo, hi) = (Wave::Level(false), Wave::Level(true));
        assert_eq!(armature(BridgeMode::PwmDir, d, lo, lo, true), Some(0.25));
        assert_eq!(armature(BridgeMode::PwmDir, d, hi, lo, true), Some(-0.25));
        assert_eq!(armature(BridgeMode::PwmIn1In2, d, hi, lo, true), Some(0.25));
        assert_eq!(
            armature(BridgeMode::PwmIn1In2, d, lo, hi, true),
            Some(-0.25)
        );
        assert_eq!(armature(BridgeMode::PwmIn1In2, hi, hi, hi, true), Some(0.0));
        assert_eq!(armature(BridgeMode::PwmIn1In2, lo, lo, lo, true), None);
        for mode in [
            BridgeMode::PwmDir,
            BridgeMode::TwoPwm,
            BridgeMode::PwmIn1In2,
        ] {
            assert_eq!(armature(mode, d, hi, lo, false), None, "{mode:?}");
        }
    }

    /// Drive → brake written as CCR = full before the lines: a state of
    /// full drive for 0.1 µs between 5 % and brake is a transient; the
    /// same update lines-first (brake, then CCR) is not; nor is a normal
    /// update whose intermediate states lie between the old and the new.
    #[test]
    fn transient_watch_flags_a_full_drive_between_stores() {
        let us = 1_000_000u128;
        let mut w = TransientWatch::default();
        assert!(w.change(0, [0.05, -0.05]).is_empty());
        // CCR = full with IN1/IN2 still forward: +1.0 for 0.1 µs.
        assert!(w.change(1000 * us, [1.0, -0.05]).is_empty());
        assert!(w.change(1000 * us + us / 10, [0.0, -0.05]).is_empty());
        // Brake held for a tick: the run closes.
        let t = w.change(2000 * us, [0.0, -0.04]);
        assert_eq!(t.len(), 1, "{t:?}");
        assert_eq!(t[0].wheel, 0);
        assert_eq!(t[0].armature, 1.0);
        assert_eq!((t[0].before, t[0].after), (0.05, 0.0));
        assert_eq!(t[0].len_ps, us / 10);
        // Lines first: brake, then CCR = full (still brake), then stable.
        let mut w = TransientWatch::default();
        w.change(0, [0.05, 0.0]);
        w.change(1000 * us, [0.0, 0.0]);
        w.change(1000 * us + us / 10, [0.0, 0.0]);
        assert!(w.change(2000 * us, [0.0, 0.0]).is_empty());
        // An ordinary update: 5 % → 7 % / −3 % → −2 %, one CCR at a time.
        let mut w = TransientWatch::default();
        w.change(0, [0.05, -0.03]);
        w.change(1000 * us, [0.07, -0.03]);
        w.change(1000 * us + us / 20, [0.07, -0.02]);
        assert!(w.change(2000 * us, [0.06, -0.02]).is_empty());
    }
}
