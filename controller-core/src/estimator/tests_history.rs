//! The compact history (history.rs, D31): inputs per tick, snapshots every
//! K ticks, replay to the measurement's tick.

use super::history::Tick;
use super::predict::Input;
use super::*;

const DT: f32 = 1e-3;
const K: usize = PoseEstimator::<HISTORY_LEN>::SNAPSHOT_EVERY;
const DEPTH: usize = PoseEstimator::<HISTORY_LEN>::GUARANTEED_DEPTH_TICKS;

fn est() -> PoseEstimator {
    PoseEstimator::new(EstimatorConfig::EXAMPLE, 0.05, Pose::new(0.0, 0.0, 0.0)).unwrap()
}

/// The robot's motion at tick k (an S-curve at 0.6 m/s) and the estimator's
/// inputs: wheels over-reporting by 20 %, a gyro biased by 0.01 rad/s.
struct Drive {
    x: f32,
    y: f32,
    th: f32,
}

impl Drive {
    fn new() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            th: 0.0,
        }
    }

    fn tick(&mut self, e: &mut PoseEstimator, k: u32) {
        let t = k as f32 * DT;
        let (v, w) = (0.6, 0.8 * (0.7 * t).sin());
        let ds = v * DT;
        let (s, c) = (self.th + 0.5 * w * DT).sin_cos();
        self.x += ds * c;
        self.y += ds * s;
        self.th += w * DT;
        let g = Some(GyroSample {
            rate_radps: w + 0.01,
            stamp_us: k * 1000,
        });
        e.predict(k * 1000, DT, 1.2 * ds, 1.1 * w * DT, g);
    }

    /// A pose of G taken now, offset from the truth by a few mm (so that
    /// every correction moves the estimate).
    fn measurement(&self, stamp_us: u32, heading: bool) -> PoseMeasurement {
        PoseMeasurement {
            stamp_us,
            pose: Pose::new(
                self.x + 0.05 * self.th.cos() + 0.003,
                self.y + 0.05 * self.th.sin() - 0.002,
                wrap_angle(self.th),
            ),
            position_std_m: 0.002,
            heading_std_rad: heading.then_some(0.005),
        }
    }
}

fn state_bits(e: &PoseEstimator) -> ([u32; 5], [[u32; 5]; 5]) {
    (
        e.filter.x.map(f32::to_bits),
        e.covariance().map(|r| r.map(f32::to_bits)),
    )
}

#[test]
fn tick_round_trips_its_inputs() {
    for (dt, gyro_used, still) in [
        (1e-3, true, false),
        (0.1, false, false),
        (1e-7, true, true),
        (0.0999, false, false),
    ] {
        let u = Input {
            dt_s: dt,
            ds_m: -0.0123,
            yaw: 3.5,
            gyro_used,
            still,
        };
        assert_eq!(Tick::new(7, &u).input(), u);
    }
    assert_eq!(core::mem::size_of::<Tick>(), 16);
}

/// The history is a few KiB: 16 B per tick plus 16 snapshots of 80 B and
/// their gyro-vs-wheel sums of 12 B (D36) (the former 104 B per tick would
/// be 28 KiB for 272 ticks).
#[test]
fn history_fits_a_few_kib() {
    let size = core::mem::size_of::<PoseEstimator<HISTORY_LEN>>();
    assert!(size <= 16 * HISTORY_LEN + 16 * (80 + 12) + 640, "{size} B");
    const { assert!(DEPTH >= 250 && K == 17) };
}

/// At every tick, the posterior the history gives for each usable past
/// tick (a snapshot or the latest fix, and the inputs replayed) is the
/// live state the filter had at that tick, bit for bit (for the ticks a
/// measurement can land on: from the latest correction's on); with on-time
/// corrections every 7 ticks (not a multiple of K, so they fall at every
/// phase between snapshots), at several ticks some twice.
#[test]
fn replayed_posterior_equals_the_live_one() {
    let mut e = est();
    let mut d = Drive::new();
    let mut live = std::vec::Vec::new();
    for k in 1..=700u32 {
        d.tick(&mut e, k);
        if k % 7 == 0 {
            e.correct(&d.measurement(k * 1000, k % 2 == 0)).unwrap();
            if k % 3 == 0 {
                e.correct(&d.measurement(k * 1000, true)).unwrap();
            }
        }
        live.push(e.filter);
        if k % 50 == 0 || k > 680 {
            // The ticks a measurement can still land on: from the latest
            // correction's on (older ones are out of order).
            let oldest = e.oldest_usable().unwrap();
            let fix = e.fix.map_or(oldest, |f| f.back);
            for back in 0..=oldest.min(fix) {
                let (f, replayed) = e.posterior_at(back);
                assert!(replayed < K, "{replayed}");
                assert_eq!(f, live[live.len() - 1 - back], "tick {k}, {back} back");
            }
        }
    }
}

/// A single measurement delivered `delay` ticks late equals the same one
/// delivered on time, bit for bit, for every phase of its tick between
/// two snapshots (on one, just after, just before the next), for delays
/// from 0 through the guaranteed depth (the oldest edge), and stamps
/// between ticks (rounded to the nearest).
#[test]
fn late_equals_on_time_at_every_snapshot_phase() {
    let delays = [0, 1, 5, K - 1, K, K + 1, 2 * K - 1, 100, DEPTH - 1, DEPTH];
    // From 400 ticks on, the history is full; the measured tick's phase
    // relative to the snapshots runs over all K values.
    for taken in 400..(400 + K as u32) {
        for &delay in &delays {
            for offset_us in [0u32, 300, 700] {
                if delay == DEPTH && offset_us > 0 {
                    continue; // older than the guaranteed depth
                }
                let run = |deliver: u32| {
                    let mut e = est();
                    let mut d = Drive::new();
                    let mut m = None;
                    for k in 1..=taken + delay as u32 + 3 {
                        d.tick(&mut e, k);
                        if k == taken {
                            // Taken between tick k − 1 and k.
                            m = Some(d.measurement(k * 1000 - offset_us, true));
                        }
                        if k == deliver {
                            e.correct(&m.unwrap()).unwrap();
                        }
                    }
                    e
                };
                let (on_time, late) = (run(taken), run(taken + delay as u32));
                assert_eq!(
                    state_bits(&on_time),
                    state_bits(&late),
                    "taken {taken}, delay {delay}, offset {offset_us} µs"
                );
                assert_eq!(on_time.status().accepted, 1);
                assert_eq!(late.status().accepted, 1);
            }
        }
    }
}

/// The oldest edge: at every phase of the snapshots, a pose taken
/// [`DEPTH`] ticks ago is used and one taken more than H ticks ago is
/// refused as too old.
#[test]
fn oldest_edge_holds_at_every_phase() {
    for extra in 0..(2 * K as u32) {
        let mut e = est();
        let mut d = Drive::new();
        let n = HISTORY_LEN as u32 + 50 + extra;
        for k in 1..=n {
            d.tick(&mut e, k);
        }
        let stamp = |age: u32| (n - age) * 1000;
        let old = d.measurement(stamp(HISTORY_LEN as u32), true);
        assert_eq!(e.correct(&old), Err(RejectReason::TooOld), "{extra}");
        // Position-only, so that the truth-now pose is not gated.
        let mut m = d.measurement(stamp(DEPTH as u32), false);
        m.position_std_m = 1.0;
        assert_eq!(e.correct(&m), Ok(()), "{extra}");
    }
}

/// The gyro-vs-wheel update of the speed scale (D36) is part of the ticks
/// the history replays: it is applied on each snapshot's tick, live and
/// re-propagated alike. With it on (the Drive's wheels over-report the yaw
/// by 10 %, so it moves the state), a measurement delivered late over one
/// to fifteen snapshot intervals, at phases before, on and after a
/// snapshot, whole or in slices of 24 ticks, gives the on-time state bit
/// for bit; and the update does change the state (it is exercised).
#[cfg(feature = "gyro-speed-scale")]
#[test]
fn late_equals_on_time_with_the_gyro_speed_scale() {
    let run = |cfg: EstimatorConfig, taken: u32, deliver: u32, slice: Option<usize>| {
        let mut e = PoseEstimator::new(cfg, 0.05, Pose::new(0.0, 0.0, 0.0)).unwrap();
        let mut d = Drive::new();
        let mut m = None;
        for k in 1..=taken + 300 {
            d.tick(&mut e, k);
            if let Some(b) = slice {
                e.resume(b);
            }
            if k == taken {
                m = Some(d.measurement(k * 1000, true));
            }
            if k == deliver {
                match slice {
                    Some(b) => e.correct_within(&m.unwrap(), b).map(|_| ()).unwrap(),
                    None => e.correct(&m.unwrap()).unwrap(),
                }
            }
        }
        e.resume(usize::MAX);
        e
    };
    let on = EstimatorConfig::EXAMPLE;
    assert!(on.gyro_speed_scale);
    let off = EstimatorConfig {
        gyro_speed_scale: false,
        ..on
    };
    for taken in [400, 400 + K as u32 - 1, 400 + K as u32, 401] {
        let on_time = run(on, taken, taken, None);
        for delay in [1, K as u32, 2 * K as u32 + 3, 100, DEPTH as u32] {
            for slice in [None, Some(24)] {
                let late = run(on, taken, taken + delay, slice);
                assert_eq!(
                    state_bits(&on_time),
                    state_bits(&late),
                    "taken {taken}, delay {delay}, slice {slice:?}"
                );
            }
        }
        assert_ne!(
            state_bits(&on_time),
            state_bits(&run(off, taken, taken, None))
        );
    }
}
