//! The motor outputs: two H-bridge channels in one of three input schemes
//! (`controller_core::runtime::BridgeMode`, chosen at boot from a
//! `BridgeParams` value), every one sign-magnitude with slow decay
//! (drive/brake), so the mean armature voltage is ±duty × V_supply as the
//! runtime's motor model assumes.
//!
//! Pins (the same on both chips; book/src/how-to/wire-a-board.md has the per-mode table):
//!
//! | pin | PwmDir | TwoPwm | PwmIn1In2 |
//! |---|---|---|---|
//! | PA8 (TIM1 CH1) | right PWM | right IN1 | right PWM |
//! | PA9 (TIM1 CH2) | left PWM | left IN1 | left PWM |
//! | PB13 | left DIR (GPIO) | right IN2 (TIM1 CH1N, AF1) | left IN1 (GPIO) |
//! | PB0 | low (unused) | left IN2 (TIM1 CH2N, AF1) | low (unused) |
//! | PB12 | right DIR (GPIO) | low (unused) | right IN1 (GPIO) |
//! | PB15 | low (unused) | low (unused) | right IN2 (GPIO) |
//! | PB1 | low (unused) | low (unused) | left IN2 (GPIO) |
//! | PB14 | ENABLE (GPIO) | ENABLE (GPIO; BTS7960 R_EN/L_EN) | STBY / ENA+ENB (GPIO) |
//!
//! **TwoPwm on one timer.** The F411CE has no fourth free TIM1 channel
//! (CH3 = PA10 would do, CH4 = PA11 is USB D−), and a second timer would
//! not be forced low by a debugger halt (only TIM1 has MOE). Each motor
//! therefore uses one TIM1 channel *and its complementary output*, one of
//! them PWM and the other held at its off-state level (RM0383 §12.4.9 /
//! RM0390 §16.4.9 and RM0090 Table 94, MOE = 1, OSSR = 1):
//!
//! * forward: CCxE = 0, CCxP = 1: IN1 (OCx) is the off-state level CCxP,
//!   **high**; CCxNE = 1, CCxNP = 0: IN2 (OCxN) = OCxREF, high while
//!   CNT < CCR; CCR = full − duty: IN2 low for the duty fraction (drive),
//!   both high for the rest (brake, slow decay);
//! * reverse mirrored: CCxNE = 0, CCxNP = 1 (IN2 high), CCxE = 1, CCxP = 0
//!   (IN1 = OCxREF), CCR = full − duty;
//! * idle (enabled, zero duty): brake = the forward setting with CCR =
//!   full (both high), coast = CCxE = 1 only, CCR = 0 (both low);
//! * disabled: CCxE = 1 only, CCR = 0: both **low** (coast; a DRV8871
//!   sleeps after 1 ms of both low).
//!
//! CCR is not preloaded (OCxPE = 0), so a direction change (CCER) and
//! the new duty (CCR) take effect together; a write mid-period gives one
//! period with a duty between the old and the new one. With MOE = 0 (fault entry, debugger
//! halt) the outputs go to their idle levels OISx = OISxN = 0 (low) "after
//! a dead-time" (0 here) "if the clock is present" (RM0090 Table 94): the
//! fault entries do not rely on it (they switch the pins to GPIO low).
//!
//! **PwmIn1In2** (TB6612FNG): PWM = duty, IN1/IN2 = 10 forward, 01
//! reverse; while PWM is low the TB6612 short-brakes (its truth table:
//! IN1/IN2 = 10 or 01 with PWM L is "short brake"), so it is drive/brake.
//! Idle brake IN1 = IN2 = high with PWM high (short brake in any case),
//! coast IN1 = IN2 = low with PWM low ("stop", outputs off). The lines and
//! the duty are separate stores: a wheel going to brake or reversing is
//! braked first (both lines high), so no state between the stores drives
//! more than the old or the new one (D148). An L298N on
//! these pins (ENx = PWM) is drive/*coast* while ENx is low, not the
//! slow decay the motor model assumes: wire it as TwoPwm (IN1/IN2 = PA8/PB13,
//! PA9/PB0, ENA/ENB to PB14) instead.

use controller_core::runtime::{BridgeMode, BridgeParams, DutyCommand, IdleMode, MotorDriver};
use defmt::{error, info};
use embassy_stm32::gpio::{Level, Output, OutputType, Pull, Speed};
use embassy_stm32::pac::timer::vals::{Ossi, Ossr};
use embassy_stm32::peripherals::{PA8, PA9, PB0, PB1, PB12, PB13, PB14, PB15, TIM1};
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, PwmPinConfig, SimplePwm, SimplePwmChannel};
use embassy_stm32::{pac, Peri};

/// TIM1's kernel clock \[Hz\] (APB2 timer clock), the same on the HSI
/// fallback: F411 APB2 = 96 MHz, its timers ×1 = 96 MHz.
#[cfg(feature = "stm32f411ce")]
pub const TIM1_CLOCK_HZ: u32 = 96_000_000;
/// TIM1's kernel clock \[Hz\] (APB2 timer clock), the same on the HSI
/// fallback: F446 APB2 = 84 MHz, its timers ×2 = 168 MHz.
#[cfg(feature = "stm32f446re")]
pub const TIM1_CLOCK_HZ: u32 = 168_000_000;

// Every robot record robot-file accepts runs on this TIM1: its
// validation checks `bridge.pwm_frequency_hz` against each of
// `SUPPORTED_TIMER_CLOCKS_HZ` (100..=65,535 duty levels), so a stored
// robot's [bridge] never reaches HBridge::new's refusal (D115).
const _: () = {
    let clocks = robot_file::SUPPORTED_TIMER_CLOCKS_HZ;
    let mut i = 0;
    let mut found = false;
    while i < clocks.len() {
        found |= clocks[i] == TIM1_CLOCK_HZ;
        i += 1;
    }
    assert!(
        found,
        "TIM1_CLOCK_HZ is not one of robot_file::SUPPORTED_TIMER_CLOCKS_HZ"
    );
};

// GPIOB lines (bit numbers).
const PB_R_DIR_IN1: u32 = 12;
const PB_L_DIR_IN1: u32 = 13;
const PB_ENABLE: u32 = 14;
const PB_R_IN2: u32 = 15;
const PB_L_IN2: u32 = 1;
const PB_L_IN2_TWO_PWM: u32 = 0;
/// Every motor line on GPIOB: PB0, PB1, PB12-PB15 (the fault entries and
/// `__pre_init` reset the same mask: BSRR 0xF003 << 16).
pub const GPIOB_MOTOR_MASK: u32 = 0xF003;

/// TIM1 CCER nibble per channel (CCxE bit 0, CCxP bit 1, CCxNE bit 2,
/// CCxNP bit 3) in TwoPwm.
const TWO_PWM_FORWARD: u32 = 0b0110; // IN1 off-state high, IN2 = OCxREF
#[cfg_attr(feature = "ci-naive-two-pwm", allow(dead_code))]
const TWO_PWM_REVERSE: u32 = 0b1001; // IN1 = OCxREF, IN2 off-state high
const CCER_MAIN_ONLY: u32 = 0b0001; // IN1 = OCxREF, IN2 off-state low

/// Two H-bridge channels in the boot-time [`BridgeMode`], with a shared
/// enable/standby line.
pub struct HBridge {
    pwm: [SimplePwmChannel<'static, TIM1>; 2],
    /// The GPIOB lines, owned (never dropped: a dropped pin is released);
    /// driven through BSRR in one store per tick.
    _lines: [Output<'static>; 5],
    enable: Output<'static>,
    mode: BridgeMode,
    idle: IdleMode,
    /// PWM counts at 100 % duty; 0 when the bridge parameters were refused
    /// (the driver then stays disabled).
    full: u16,
    enabled: bool,
}

impl HBridge {
    /// Binds TIM1 and the motor pins for `bridge` and leaves every line low
    /// (disabled). Refuses (defmt error, the driver stays disabled with
    /// [`Self::full_scale`] 0, which the runtime's configuration check
    /// rejects) a frequency outside `BridgeParams::PWM_FREQUENCY_RANGE_HZ`
    /// or one whose duty resolution does not fit TIM1 at [`TIM1_CLOCK_HZ`]
    /// (`BridgeParams::duty_full_scale`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        tim1: Peri<'static, TIM1>,
        pa8: Peri<'static, PA8>,
        pa9: Peri<'static, PA9>,
        pb0: Peri<'static, PB0>,
        pb1: Peri<'static, PB1>,
        pb12: Peri<'static, PB12>,
        pb13: Peri<'static, PB13>,
        pb14: Peri<'static, PB14>,
        pb15: Peri<'static, PB15>,
        bridge: BridgeParams,
    ) -> Self {
        // Driver disabled before anything else touches the PWM timer.
        let enable = Output::new(pb14, Level::Low, Speed::Low);
        let lines = [
            Output::new(pb0, Level::Low, Speed::Low),
            Output::new(pb1, Level::Low, Speed::Low),
            Output::new(pb12, Level::Low, Speed::Low),
            Output::new(pb13, Level::Low, Speed::Low),
            Output::new(pb15, Level::Low, Speed::Low),
        ];
        let full = match bridge.validate() {
            Ok(b) => b.duty_full_scale(TIM1_CLOCK_HZ),
            Err(_) => None,
        };
        let freq_hz = match full {
            Some(_) => bridge.pwm_frequency_hz,
            None => {
                error!(
                    "bridge: PWM frequency {=u32} Hz refused (range {=u32}-{=u32} Hz, at most 65 535 and at least 100 TIM1 counts at {=u32} Hz); motors stay disabled",
                    bridge.pwm_frequency_hz,
                    BridgeParams::PWM_FREQUENCY_RANGE_HZ.0,
                    BridgeParams::PWM_FREQUENCY_RANGE_HZ.1,
                    TIM1_CLOCK_HZ
                );
                BridgeParams::EXAMPLE.pwm_frequency_hz
            }
        };
        // Pull-downs hold PA8/PA9 low between the switch to TIM1 and CCxE = 1.
        let pin_cfg = PwmPinConfig {
            output_type: OutputType::PushPull,
            speed: Speed::Low, // 20 kHz needs no fast edges; slower edges ring less
            pull: Pull::Down,
        };
        let pwm = SimplePwm::new(
            tim1,
            Some(PwmPin::new_with_config(pa8, pin_cfg)),
            Some(PwmPin::new_with_config(pa9, pin_cfg)),
            None,
            None,
            embassy_stm32::time::Hertz(freq_hz),
            CountingMode::EdgeAlignedUp,
        );
        let t = pac::TIM1;
        // The period exactly as BridgeParams::duty_full_scale says:
        // PSC = 0, ARR + 1 = clock / frequency (embassy rounds its own way).
        if let Some(n) = full {
            t.psc().write_value(0);
            t.arr().write(|w| w.set_arr(n - 1));
            t.egr().write(|w| w.set_ug(true));
        }
        // Idle (MOE = 0: fault, debugger halt): OISx = OISxN = 0 with
        // OSSI = 1, the outputs driven low rather than released. Run
        // (MOE = 1): OSSR = 1, a disabled half of a complementary pair
        // drives its off-state level CCxP / CCxNP (TwoPwm) instead of
        // floating.
        t.cr2().modify(|w| {
            for ch in 0..2 {
                w.set_ois(ch, false);
                w.set_oisn(ch, false);
            }
        });
        t.bdtr().modify(|w| {
            w.set_ossi(Ossi::IDLE_LEVEL);
            w.set_ossr(Ossr::IDLE_LEVEL);
        });
        // CCR written at once (OCxPE = 0), not at the next update event:
        // the direction lines (GPIO, or CCER in TwoPwm) change at once, so
        // a preloaded duty would run the new direction at the old duty for
        // up to one PWM period; in TwoPwm, where zero duty is CCR = full,
        // that is a full-voltage pulse on every arming (stm32-emu's check
        // (j) found it: a 50 µs reverse pulse at 100 % on `wmr drive`).
        // Unbuffered, a write mid-period gives one period with a duty
        // between the old and the new one.
        t.ccmr_output(0).modify(|w| {
            w.set_ocpe(0, false);
            w.set_ocpe(1, false);
        });
        let ch = pwm.split();
        let mut pwm = [ch.ch1, ch.ch2];
        for c in &mut pwm {
            c.set_duty_cycle(0);
            c.enable();
        }
        if bridge.mode == BridgeMode::TwoPwm {
            // PB13 = TIM1_CH1N, PB0 = TIM1_CH2N (AF1 on both chips:
            // DS10314 table 9, DS10693 table 11): pull-down, then AF.
            let b = pac::GPIOB;
            b.pupdr().modify(|w| {
                w.set_pupdr(PB_L_DIR_IN1 as usize, pac::gpio::vals::Pupdr::PULL_DOWN);
                w.set_pupdr(PB_L_IN2_TWO_PWM as usize, pac::gpio::vals::Pupdr::PULL_DOWN);
            });
            b.afr(1)
                .modify(|w| w.set_afr((PB_L_DIR_IN1 - 8) as usize, 1));
            b.afr(0).modify(|w| w.set_afr(PB_L_IN2_TWO_PWM as usize, 1));
            b.moder().modify(|w| {
                w.set_moder(PB_L_DIR_IN1 as usize, pac::gpio::vals::Moder::ALTERNATE);
                w.set_moder(PB_L_IN2_TWO_PWM as usize, pac::gpio::vals::Moder::ALTERNATE);
            });
        }
        let mut this = Self {
            pwm,
            _lines: lines,
            enable,
            mode: bridge.mode,
            idle: bridge.idle,
            full: full.unwrap_or(0),
            enabled: false,
        };
        this.disable();
        if this.full != 0 {
            info!(
                "bridge: {} at {=u32} Hz ({=u16} counts), idle {}",
                bridge.mode, freq_hz, this.full, bridge.idle
            );
        }
        this
    }

    /// PWM counts at 100 % duty (the timer's resolution at the bridge's
    /// frequency); 0 when the bridge parameters were refused.
    pub fn full_scale(&self) -> u32 {
        if self.full == 0 {
            0
        } else {
            self.pwm[0].max_duty_cycle()
        }
    }
}

/// GPIOB BSRR: set `pin` when `high`, else reset it.
#[inline(always)]
fn bsrr_bit(pin: u32, high: bool) -> u32 {
    if high {
        1 << pin
    } else {
        1 << (pin + 16)
    }
}

#[inline(always)]
fn write_ccr(ch: usize, value: u32) {
    pac::TIM1
        .ccr(ch)
        .write_value(pac::timer::regs::Ccr1ch(value));
}

/// The PWM channels stay enabled (CCxE = 1, MOE = 1) in every state: with
/// CCR = 0, PWM mode 1 keeps OCxREF low, so the timer drives the pins low.
/// Clearing CCxE instead (with OSSR = 0) would release the pins to the GPIO
/// controller: floating, the defect this layout avoids.
impl MotorDriver for HBridge {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        if self.full == 0 {
            self.disable();
            return;
        }
        let full = self.full as u32;
        let mut bsrr = 0u32;
        match self.mode {
            BridgeMode::PwmDir => {
                for (i, (pin, c)) in [PB_R_DIR_IN1, PB_L_DIR_IN1]
                    .into_iter()
                    .zip(cmd)
                    .enumerate()
                {
                    bsrr |= bsrr_bit(pin, c.reverse);
                    write_ccr(i, (c.duty as u32).min(full));
                }
            }
            BridgeMode::PwmIn1In2 => {
                // The lines (GPIO) and the duty (CCR) are two stores, and
                // every state between them is driven (for a few
                // instructions, or an interrupt's length). Ordered so that
                // none drives more than the old or the new state: a wheel
                // going to brake, or reversing, is braked first (IN1 = IN2
                // = high: short brake at any PWM), then CCR, then the
                // lines. Written the other way round, drive → brake passed
                // through the old direction at CCR = full: the whole
                // supply (stm32-emu's bridge transients, D148).
                let pins = [(PB_R_DIR_IN1, PB_R_IN2), (PB_L_DIR_IN1, PB_L_IN2)];
                let odr = pac::GPIOB.odr().read().0;
                let mut brake_first = 0u32;
                let mut ccr = [0u32; 2];
                for (i, ((in1, in2), c)) in pins.into_iter().zip(cmd).enumerate() {
                    let (a, b, duty) = match (c.duty, self.idle) {
                        (0, IdleMode::Brake) => (true, true, full),
                        (0, IdleMode::Coast) => (false, false, 0),
                        (d, _) => (!c.reverse, c.reverse, (d as u32).min(full)),
                    };
                    let was = ((odr >> in1) & 1 != 0, (odr >> in2) & 1 != 0);
                    let reversing = a != b && was.0 != was.1 && was.0 != a;
                    if (a && b) || reversing {
                        brake_first |= bsrr_bit(in1, true) | bsrr_bit(in2, true);
                    }
                    bsrr |= bsrr_bit(in1, a) | bsrr_bit(in2, b);
                    ccr[i] = duty;
                }
                if brake_first != 0 {
                    pac::GPIOB
                        .bsrr()
                        .write_value(pac::gpio::regs::Bsrr(brake_first));
                }
                write_ccr(0, ccr[0]);
                write_ccr(1, ccr[1]);
            }
            BridgeMode::TwoPwm => {
                let mut ccer = 0u32;
                for (i, c) in cmd.into_iter().enumerate() {
                    let (nibble, ccr) = match (c.duty, self.idle) {
                        (0, IdleMode::Brake) => (TWO_PWM_FORWARD, full),
                        (0, IdleMode::Coast) => (CCER_MAIN_ONLY, 0),
                        // stm32-emu's negative control: IN1 = duty PWM, IN2 =
                        // the direction level (reverse: IN2 high, so the
                        // motor is driven in reverse for 1 − duty).
                        #[cfg(feature = "ci-naive-two-pwm")]
                        (d, _) => (
                            if c.reverse { 0b1001 } else { CCER_MAIN_ONLY },
                            (d as u32).min(full),
                        ),
                        #[cfg(not(feature = "ci-naive-two-pwm"))]
                        (d, _) => (
                            if c.reverse {
                                TWO_PWM_REVERSE
                            } else {
                                TWO_PWM_FORWARD
                            },
                            full - (d as u32).min(full),
                        ),
                    };
                    ccer |= nibble << (4 * i);
                    write_ccr(i, ccr);
                }
                pac::TIM1.ccer().modify(|w| w.0 = (w.0 & !0xFF) | ccer);
            }
        }
        bsrr |= bsrr_bit(PB_ENABLE, true);
        pac::GPIOB.bsrr().write_value(pac::gpio::regs::Bsrr(bsrr));
        self.enabled = true;
    }

    fn disable(&mut self) {
        self.enable.set_low();
        // Every GPIOB motor line low (a no-op on the AF pins).
        pac::GPIOB
            .bsrr()
            .write_value(pac::gpio::regs::Bsrr(GPIOB_MOTOR_MASK << 16));
        write_ccr(0, 0);
        write_ccr(1, 0);
        // Both channels: OCx = OCxREF (low at CCR = 0), OCxN off-state low.
        pac::TIM1
            .ccer()
            .modify(|w| w.0 = (w.0 & !0xFF) | CCER_MAIN_ONLY | (CCER_MAIN_ONLY << 4));
        self.enabled = false;
    }
}
