//! Board support: chip, clocks, pins, timers and loop rates. Porting to
//! another board means editing this file (and the chip feature) only.
//!
//! Pin map (identical on both supported chips except the button):
//!
//! | function | pin | peripheral |
//! |---|---|---|
//! | right encoder A / B | PA6 / PA7 | TIM3 CH1 / CH2, encoder mode |
//! | left encoder A / B | PB6 / PB7 | TIM4 CH1 / CH2, encoder mode |
//! | right motor PWM | PA8 | TIM1 CH1, 20 kHz |
//! | left motor PWM | PA9 | TIM1 CH2, 20 kHz |
//! | right motor DIR | PB12 | GPIO out (high = reverse) |
//! | left motor DIR | PB13 | GPIO out (high = reverse) |
//! | driver ENABLE (both) | PB14 | GPIO out (high = enabled, low at boot) |
//! | arm button | PA0 (F411 "KEY") / PC13 (Nucleo B1) | GPIO in, pull-up, active low |
//!
//! TIM5 is embassy's time driver; TIM2 is free.

use controller_core::runtime::{DutyCommand, Encoder, MotorDriver};
use embassy_stm32::gpio::{Input, Level, Output, OutputType, Pull, Speed};
use embassy_stm32::peripherals::{IWDG, TIM1, TIM3, TIM4};
use embassy_stm32::time::{khz, Hertz};
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm, SimplePwmChannel};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{pac, rcc, Config};

#[cfg(all(feature = "stm32f411ce", feature = "stm32f446re"))]
compile_error!("select exactly one chip feature: stm32f411ce or stm32f446re");
#[cfg(not(any(feature = "stm32f411ce", feature = "stm32f446re")))]
compile_error!("select a chip feature: stm32f411ce (default) or stm32f446re");

/// Chip name for the banner.
#[cfg(feature = "stm32f411ce")]
pub const CHIP: &str = "STM32F411CE (Black Pill), HSE 25 MHz -> SYSCLK 96 MHz";
/// Chip name for the banner.
#[cfg(feature = "stm32f446re")]
pub const CHIP: &str = "STM32F446RE (Nucleo-64), HSE 8 MHz bypass -> SYSCLK 180 MHz";

/// Core clock \[Hz\] (DWT cycle counts are in these cycles).
#[cfg(feature = "stm32f411ce")]
pub const SYSCLK_HZ: u32 = 96_000_000;
/// Core clock \[Hz\] (DWT cycle counts are in these cycles).
#[cfg(feature = "stm32f446re")]
pub const SYSCLK_HZ: u32 = 180_000_000;

/// Control loop rate \[Hz\] (must match the controller's `period_s`).
pub const CONTROL_HZ: u64 = 1000;
/// Motor PWM frequency (inaudible, and well above the 1 kHz loop).
pub const PWM_FREQ: Hertz = khz(20);
/// Independent watchdog timeout \[µs\]; the control task feeds it every tick.
pub const WATCHDOG_TIMEOUT_US: u32 = 50_000;
/// Telemetry every this many ticks (50 -> 20 Hz at 1 kHz).
pub const TELEMETRY_DECIMATION: u32 = 50;
/// Button debounce \[ticks\]: pressed this long counts as one press.
pub const BUTTON_DEBOUNCE_TICKS: u16 = 20;

/// Clock tree of the selected chip.
pub fn clock_config() -> Config {
    use rcc::*;
    let mut config = embassy_stm32::Config::default();
    #[cfg(feature = "stm32f411ce")]
    {
        // 25 MHz crystal /25 ×192 = 192 MHz VCO; /2 = 96 MHz SYSCLK, /4 = 48 MHz (USB).
        config.rcc.hse = Some(Hse {
            freq: Hertz(25_000_000),
            mode: HseMode::Oscillator,
        });
        config.rcc.pll_src = PllSource::HSE;
        config.rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV25,
            mul: PllMul::MUL192,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV4),
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV2; // 48 MHz (max 50); timers ×2 = 96 MHz
        config.rcc.apb2_pre = APBPrescaler::DIV1; // 96 MHz: TIM1 at 96 MHz
        config.rcc.sys = Sysclk::PLL1_P;
    }
    #[cfg(feature = "stm32f446re")]
    {
        // ST-LINK MCO 8 MHz (bypass) /4 ×180 = 360 MHz VCO; /2 = 180 MHz SYSCLK.
        config.rcc.hse = Some(Hse {
            freq: Hertz(8_000_000),
            mode: HseMode::Bypass,
        });
        config.rcc.pll_src = PllSource::HSE;
        config.rcc.pll = Some(Pll {
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL180,
            divp: Some(PllPDiv::DIV2),
            divq: None,
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV4; // 45 MHz; timers 90 MHz
        config.rcc.apb2_pre = APBPrescaler::DIV2; // 90 MHz; TIM1 at 180 MHz
        config.rcc.sys = Sysclk::PLL1_P;
    }
    config
}

/// One quadrature encoder on a timer in encoder mode (×4 decoding).
pub struct QeiEncoder<T: embassy_stm32::timer::GeneralInstance4Channel>(Qei<'static, T>);

impl<T: embassy_stm32::timer::GeneralInstance4Channel> Encoder for QeiEncoder<T> {
    fn count(&mut self) -> u16 {
        self.0.count()
    }
}

/// Both encoders, `(right, left)`.
pub type Encoders = (QeiEncoder<TIM3>, QeiEncoder<TIM4>);

/// Two sign-magnitude H-bridge channels (PWM + DIR) with a shared enable.
pub struct HBridge {
    pwm: [SimplePwmChannel<'static, TIM1>; 2],
    dir: [Output<'static>; 2],
    enable: Output<'static>,
    enabled: bool,
}

impl HBridge {
    /// PWM counts at 100 % duty (the timer's resolution at [`PWM_FREQ`]).
    pub fn full_scale(&self) -> u32 {
        self.pwm[0].max_duty_cycle()
    }
}

impl MotorDriver for HBridge {
    fn set(&mut self, cmd: [DutyCommand; 2]) {
        for ((ch, dir), c) in self.pwm.iter_mut().zip(self.dir.iter_mut()).zip(cmd) {
            dir.set_level(if c.reverse { Level::High } else { Level::Low });
            ch.set_duty_cycle(c.duty as u32);
        }
        if !self.enabled {
            for ch in &mut self.pwm {
                ch.enable();
            }
            self.enable.set_high();
            self.enabled = true;
        }
    }

    fn disable(&mut self) {
        self.enable.set_low();
        for ch in &mut self.pwm {
            ch.set_duty_cycle(0);
        }
        if self.enabled {
            for ch in &mut self.pwm {
                ch.disable();
            }
            self.enabled = false;
        }
    }
}

/// The arm button (active low).
pub struct ArmButton(Input<'static>);

impl ArmButton {
    /// True while pressed.
    pub fn pressed(&self) -> bool {
        self.0.is_low()
    }
}

/// Everything the control task drives.
pub struct Board {
    /// `(right, left)` encoders.
    pub encoders: Encoders,
    /// Motor driver, disabled.
    pub motors: HBridge,
    /// Arm / disarm / reset button.
    pub button: ArmButton,
    /// Independent watchdog (configured, not yet started).
    pub watchdog: IndependentWatchdog<'static, IWDG>,
}

/// Initialises clocks and binds the peripherals. Motor outputs start off:
/// ENABLE low, duty 0, PWM channels disabled.
pub fn init() -> Board {
    let p = embassy_stm32::init(clock_config());
    // Driver disabled before anything else touches the PWM timer.
    let enable = Output::new(p.PB14, Level::Low, Speed::Low);
    let dir = [
        Output::new(p.PB12, Level::Low, Speed::Low),
        Output::new(p.PB13, Level::Low, Speed::Low),
    ];
    let pwm = SimplePwm::new(
        p.TIM1,
        Some(PwmPin::new(p.PA8, OutputType::PushPull)),
        Some(PwmPin::new(p.PA9, OutputType::PushPull)),
        None,
        None,
        PWM_FREQ,
        CountingMode::EdgeAlignedUp,
    );
    let ch = pwm.split();
    let mut pwm = [ch.ch1, ch.ch2];
    for c in &mut pwm {
        c.set_duty_cycle(0);
        c.disable();
    }
    let encoders = (
        QeiEncoder(Qei::new(p.TIM3, p.PA6, p.PA7, qei_config())),
        QeiEncoder(Qei::new(p.TIM4, p.PB6, p.PB7, qei_config())),
    );
    #[cfg(feature = "stm32f411ce")]
    let button = ArmButton(Input::new(p.PA0, Pull::Up));
    #[cfg(feature = "stm32f446re")]
    let button = ArmButton(Input::new(p.PC13, Pull::Up));

    // Keep the watchdog counting while a debugger halts the core? No: freeze
    // it, so breakpoints do not reset the board (motors are off when halted
    // only if the driver's ENABLE is low, so never debug with wheels on the floor).
    pac::DBGMCU.apb1fzr().modify(|w| w.set_iwdg(true));
    let watchdog = IndependentWatchdog::new(p.IWDG, WATCHDOG_TIMEOUT_US);

    Board {
        encoders,
        motors: HBridge {
            pwm,
            dir,
            enable,
            enabled: false,
        },
        button,
        watchdog,
    }
}

fn qei_config() -> qei::Config {
    qei::Config {
        ch1_pull: Pull::Up, // open-collector encoders need pull-ups
        ch2_pull: Pull::Up,
        ..qei::Config::default() // mode 3 (×4), full 16-bit range
    }
}

/// Turns the motor outputs off with raw register writes, usable from the
/// panic and fault handlers whatever state the drivers are in: ENABLE and
/// DIR low, TIM1 outputs disabled (MOE = 0, CCR = 0), PWM pins forced to
/// GPIO output low.
pub fn motors_off_raw() {
    // ENABLE (PB14), DIR (PB12, PB13) low.
    pac::GPIOB.bsrr().write(|w| {
        w.set_br(14, true);
        w.set_br(12, true);
        w.set_br(13, true);
    });
    pac::TIM1.bdtr().modify(|w| w.set_moe(false));
    pac::TIM1.ccr(0).write(|w| w.set_ccr(0));
    pac::TIM1.ccr(1).write(|w| w.set_ccr(0));
    // PA8, PA9: output low (not floating on the driver's PWM input).
    pac::GPIOA.bsrr().write(|w| {
        w.set_br(8, true);
        w.set_br(9, true);
    });
    pac::GPIOA.moder().modify(|w| {
        w.set_moder(8, pac::gpio::vals::Moder::OUTPUT);
        w.set_moder(9, pac::gpio::vals::Moder::OUTPUT);
    });
}
