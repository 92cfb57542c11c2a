//! The gyro's logic above the registers (robot_app::imu): conversions
//! against hand arithmetic, the probe and read-back decisions against the
//! MPU-6050 register map, the frozen/implausible monitor against a frozen
//! and a live (noisy) sequence, the retry backoff, and the cell the board's
//! gyro reads (an invalid gyro reads as none: the estimator's wheel path).

use controller_core::estimator::GyroSample;
use controller_core::runtime::Gyro;
use robot_app::imu::*;

const Z_UP: YawMapping = YawMapping {
    axis: Axis::Z,
    inverted: false,
};
const DEG: f32 = core::f32::consts::PI / 180.0;

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol
}

/// ±500 °/s: 32 767 counts = 32 767 / 65.5 °/s = 500.26 °/s = 8.7312 rad/s
/// (500.26 × 0.0174533); 65.5 counts = 1 °/s; the other axes ignored; an
/// inverted axis flips the sign.
#[test]
fn counts_to_rad_per_s_by_hand() {
    assert!(close(GyroRange::Dps500.limit_radps(), 8.7313, 1e-3));
    assert!(close(
        yaw_rate_radps([0, 0, 32_767], Z_UP, GyroRange::Dps500),
        8.7310,
        1e-3
    ));
    assert_eq!(
        yaw_rate_radps([1000, -1000, 0], Z_UP, GyroRange::Dps500),
        0.0
    );
    let y_down = YawMapping {
        axis: Axis::Y,
        inverted: true,
    };
    assert!(close(
        yaw_rate_radps([0, 131, 0], y_down, GyroRange::Dps1000),
        -131.0 / 32.8 * DEG,
        1e-6
    ));
    let x_up = YawMapping {
        axis: Axis::X,
        inverted: false,
    };
    assert!(close(
        yaw_rate_radps([-16_400, 0, 0], x_up, GyroRange::Dps2000),
        -1000.0 * DEG,
        1e-3
    ));
}

/// WHO_AM_I: the three known chips; all zeros / all ones are stuck lines.
#[test]
fn probe_decision() {
    assert_eq!(identify(0x68), Ok(ImuChip::Mpu6050));
    assert_eq!(identify(0x70), Ok(ImuChip::Mpu6500));
    assert_eq!(identify(0x71), Ok(ImuChip::Mpu9250));
    assert_eq!(identify(0xFF), Err(ImuFault::NoChip(0xFF)));
    assert_eq!(identify(0x00), Err(ImuFault::NoChip(0)));
    assert_eq!(identify(0x98), Err(ImuFault::UnknownChip(0x98)));
}

/// The read-back check: FS_SEL = 1 is 0x08 in GYRO_CONFIG; self-test bits
/// (7:5) set fail; the FSYNC bits of CONFIG (5:3) are not ours.
#[test]
fn config_read_back() {
    assert!(check_config(0x02, 0x08, 2, GyroRange::Dps500));
    assert!(check_config(0x0A, 0x08, 2, GyroRange::Dps500));
    assert!(!check_config(0x02, 0x18, 2, GyroRange::Dps500));
    assert!(!check_config(0x02, 0x88, 2, GyroRange::Dps500));
    assert!(!check_config(0x03, 0x08, 2, GyroRange::Dps500));
}

/// PWR_MGMT_1 (register map rev 4.2, register 107): 0x40 is the reset
/// value (SLEEP, internal oscillator), what a chip that browned out reads;
/// 0x80 DEVICE_RESET in progress; 0x21 CYCLE; 0x00 awake on the 8 MHz
/// oscillator (not what was written). 0x09 (TEMP_DIS) is awake on the PLL.
#[test]
fn a_sleeping_chip_is_rejected() {
    assert_eq!(check_awake(PWR_MGMT_1_AWAKE_PLL_X), Ok(()));
    assert_eq!(check_awake(0x09), Ok(()));
    for v in [0x40u8, 0x41, 0x80, 0x21, 0x00] {
        assert_eq!(check_awake(v), Err(ImuFault::NotAwake(v)), "{v:#x}");
    }
    assert!(ImuFault::Timeout.needs_bus_recovery());
    assert!(ImuFault::Bus.needs_bus_recovery());
    assert!(!ImuFault::NoAck.needs_bus_recovery());
    assert!(!ImuFault::NotAwake(0x40).needs_bus_recovery());
}

const CFG: MonitorConfig = MonitorConfig {
    frozen_after: 50,
    max_rate_radps: 25.0,
};

fn monitor(range: GyroRange) -> GyroMonitor {
    GyroMonitor::new(CFG, Z_UP, range).expect("valid")
}

/// Deterministic noise: a live gyro at rest, about ±3 counts per axis.
fn noisy(k: u32) -> [i16; 3] {
    let mut x = k.wrapping_mul(0x9E37_79B9) ^ 0x5bd1_e995;
    let mut axis = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        (x % 7) as i16 - 3
    };
    [axis(), axis(), 40 + axis()]
}

/// A chip that goes to sleep (brown-out) keeps returning its last output:
/// identical readings. The monitor passes the first `frozen_after - 1`
/// repeats (a live chip can repeat a few), reports the gyro frozen at the
/// `frozen_after`-th, counts one episode however long it lasts, and clears
/// when the readings change again. 10 000 readings of a live (noisy) gyro
/// are never frozen (independent of the detector: the noise is a hash).
#[test]
fn a_frozen_gyro_is_reported_invalid_after_n_identical_readings() {
    let mut m = monitor(GyroRange::Dps500);
    for k in 0..10_000 {
        assert!(
            matches!(m.check(noisy(k)), Verdict::Valid(_)),
            "live reading {k} rejected"
        );
    }
    assert_eq!(m.counts(), MonitorCounts::default());

    let stuck = [12, -7, 300];
    for k in 1..CFG.frozen_after {
        assert!(matches!(m.check(stuck), Verdict::Valid(_)), "repeat {k}");
    }
    for _ in 0..500 {
        assert_eq!(m.check(stuck), Verdict::Frozen);
        assert!(m.is_frozen());
    }
    assert_eq!(m.counts().frozen_episodes, 1);
    // The chip is back (reconfigured): readings change, valid again.
    let v = m.check(noisy(1));
    assert!(matches!(v, Verdict::Valid(_)), "{v:?}");
    assert!(!m.is_frozen());
    // A second freeze is a second episode.
    for _ in 0..CFG.frozen_after {
        m.check([0, 0, 0]);
    }
    assert_eq!(m.counts().frozen_episodes, 2);
    // restart() forgets the history: the same reading after a
    // reconfiguration starts a new count.
    m.restart();
    assert!(matches!(m.check([0, 0, 0]), Verdict::Valid(_)));
}

/// At ±2000 °/s the chip reports up to 34.9 rad/s: a reading of 30 rad/s
/// (1719 °/s × 16.4 = 28 190 counts) on any axis is beyond the 25 rad/s
/// bound and discarded, counted; 20 rad/s (18 793 counts) passes. At
/// ±500 °/s the chip cannot exceed 8.73 rad/s: nothing is implausible.
#[test]
fn an_implausible_rate_on_any_axis_is_discarded_and_counted() {
    let mut m = monitor(GyroRange::Dps2000);
    let counts = |radps: f32| (radps / DEG * 16.4) as i16;
    assert_eq!(m.check([counts(30.0), 0, 0]), Verdict::Implausible);
    assert_eq!(m.check([0, 0, -counts(30.0)]), Verdict::Implausible);
    let v = m.check([0, 1, counts(20.0)]);
    assert!(
        matches!(v, Verdict::Valid(r) if close(r, 20.0, 0.01)),
        "{v:?}"
    );
    assert_eq!(m.counts().implausible, 2);

    let mut m = monitor(GyroRange::Dps500);
    assert!(matches!(
        m.check([i16::MIN, i16::MAX, i16::MIN]),
        Verdict::Valid(_)
    ));
}

#[test]
fn monitor_configuration_is_validated() {
    let bad = |frozen_after, max_rate_radps| {
        GyroMonitor::new(
            MonitorConfig {
                frozen_after,
                max_rate_radps,
            },
            Z_UP,
            GyroRange::Dps500,
        )
        .err()
    };
    assert_eq!(bad(1, 25.0), Some(MonitorConfigError::FrozenAfterTooSmall));
    assert_eq!(bad(50, 0.0), Some(MonitorConfigError::MaxRateInvalid));
    assert_eq!(bad(50, f32::NAN), Some(MonitorConfigError::MaxRateInvalid));
    assert_eq!(
        bad(50, f32::INFINITY),
        Some(MonitorConfigError::MaxRateInvalid)
    );
    assert_eq!(bad(50, 25.0), None);
}

/// 100 ms, then doubling to the 5 s cap, forever; a success starts over.
#[test]
fn retry_backoff_doubles_to_its_cap_and_restarts_after_a_success() {
    let mut b = Backoff::new(100, 5_000);
    let waits: Vec<u32> = (0..9).map(|_| b.next_wait_ms()).collect();
    assert_eq!(
        waits,
        [100, 200, 400, 800, 1600, 3200, 5000, 5000, 5000],
        "doubling, capped"
    );
    b.reset();
    assert_eq!(b.next_wait_ms(), 100);
    // Degenerate arguments never give a zero wait (a busy loop).
    assert_eq!(Backoff::new(0, 0).next_wait_ms(), 1);
    assert_eq!(Backoff::new(800, 200).next_wait_ms(), 200);
}

/// The board's gyro reads the cell: none at first, the published sample,
/// none again once the IMU task invalidates it (a frozen or sleeping
/// chip): the estimator then predicts with the wheels at once.
#[test]
fn an_invalidated_gyro_reads_as_none() {
    static CELL: GyroCell = GyroCell::new();
    let mut g = CELL.reader();
    assert_eq!(g.sample(), None);
    let s = GyroSample {
        rate_radps: 0.25,
        stamp_us: 1234,
    };
    CELL.publish(s);
    assert_eq!(g.sample(), Some(s));
    CELL.invalidate();
    assert_eq!(g.sample(), None);
}

/// An I2C bus with a slave that holds SDA low until it has seen `hold`
/// falling SCL edges (a byte it was transmitting, cut off), or forever.
struct StuckSlave {
    hold: Option<u32>,
    falls: u32,
    scl: bool,
    master_sda: bool,
    /// (scl, sda) line levels after every change.
    trace: Vec<(bool, bool)>,
}

impl StuckSlave {
    fn new(hold: Option<u32>) -> Self {
        Self {
            hold,
            falls: 0,
            scl: true,
            master_sda: true,
            trace: Vec::new(),
        }
    }
    fn slave_holds(&self) -> bool {
        self.hold.is_none_or(|h| self.falls < h)
    }
    fn sda(&self) -> bool {
        self.master_sda && !self.slave_holds()
    }
}

impl RecoveryPins for StuckSlave {
    fn set_scl(&mut self, high: bool) {
        if self.scl && !high {
            self.falls += 1;
        }
        self.scl = high;
        self.trace.push((self.scl, self.sda()));
    }
    fn set_sda(&mut self, high: bool) {
        self.master_sda = high;
        self.trace.push((self.scl, self.sda()));
    }
    fn sda_is_high(&mut self) -> bool {
        self.sda()
    }
    fn half_period(&mut self) {}
}

/// A slave that lets go after k clocks (k = 0..=9) is freed with exactly k
/// pulses, and the sequence ends in a STOP (SDA rising while SCL is high)
/// with both lines released; a line clamped low is reported after the
/// nine pulses, not clocked forever.
#[test]
fn bus_recovery_clocks_a_stuck_slave_free_then_sends_a_stop() {
    for k in 0..=9u32 {
        let mut bus = StuckSlave::new(Some(k));
        assert_eq!(
            recover_bus(&mut bus),
            Recovery::Freed { pulses: k as u8 },
            "slave releasing after {k} clocks"
        );
        let t = &bus.trace;
        let n = t.len();
        assert_eq!(t[n - 1], (true, true), "both lines released");
        assert_eq!(t[n - 2], (true, false), "SDA low while SCL high, then ...");
        assert_eq!(bus.falls, k + 1, "k pulses and the STOP's SCL low");
    }
    let mut shorted = StuckSlave::new(None);
    assert_eq!(recover_bus(&mut shorted), Recovery::StillHeld);
    assert_eq!(shorted.falls, RECOVERY_PULSES as u32 + 1);
}
