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
//! | IMU SCL / SDA (`imu` feature) | PB8 / PB9 | I2C1 (AF4), 400 kHz, DMA1 stream 6 (TX) / 0 (RX) |
//!
//! TIM5 is embassy's time driver; TIM2 is free. The host link takes PA11/PA12
//! (USB, F411) or PA2/PA3 (USART2, F446).
//!
//! Motor outputs are never left floating by the firmware: [`outputs_low_early`]
//! drives them low before the clocks start, the PWM channels stay enabled
//! with a zero compare value while disarmed (driven low by TIM1, not
//! released), TIM1 forces them low when a debugger halts the core, and
//! the fault and panic entries (`fault.rs`) cut everything with
//! register-only stores before they touch the stack. Between reset
//! and the first instruction only the external pull-downs hold them (see
//! the pin-state table of book/src/how-to/wire-a-board.md).

use controller_core::runtime::{BridgeParams, Encoder, WheelOdometryOnly};
use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::pac::timer::vals::FilterValue;
use embassy_stm32::peripherals::{FLASH, IWDG, TIM3, TIM4};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{pac, rcc, Config, Peri};

/// The gyro the control tick samples: the IMU task's newest sample with
/// the `imu` feature, none without.
#[cfg(feature = "imu")]
pub type BoardGyro = crate::imu::ImuGyro;
/// The gyro the control tick samples: the IMU task's newest sample with
/// the `imu` feature, none without.
#[cfg(not(feature = "imu"))]
pub type BoardGyro = controller_core::runtime::NoGyro;

#[cfg(all(feature = "stm32f411ce", feature = "stm32f446re"))]
compile_error!("select exactly one chip feature: stm32f411ce or stm32f446re");
#[cfg(not(any(feature = "stm32f411ce", feature = "stm32f446re")))]
compile_error!("select a chip feature: stm32f411ce (default) or stm32f446re");

/// Chip name for the host link's handshake (at most 16 bytes).
#[cfg(feature = "stm32f411ce")]
pub const CHIP_ID: &str = "stm32f411ce";
/// Chip name for the host link's handshake (at most 16 bytes).
#[cfg(feature = "stm32f446re")]
pub const CHIP_ID: &str = "stm32f446re";

/// Chip name for the banner.
#[cfg(feature = "stm32f411ce")]
pub const CHIP: &str = "STM32F411CE (Black Pill), HSE 25 MHz -> SYSCLK 96 MHz";
/// Chip name for the banner.
#[cfg(feature = "stm32f446re")]
pub const CHIP: &str = "STM32F446RE (Nucleo-64), HSE 8 MHz bypass -> SYSCLK 168 MHz";

/// Core clock \[Hz\] (DWT cycle counts are in these cycles); the same on
/// the HSI fallback.
#[cfg(feature = "stm32f411ce")]
pub const SYSCLK_HZ: u32 = 96_000_000;
/// Core clock \[Hz\] (DWT cycle counts are in these cycles); the same on
/// the HSI fallback. 168 MHz rather than the chip's 180 MHz so that the
/// main PLL's Q output gives the 48 MHz USB clock (see [`clock_config`]).
#[cfg(feature = "stm32f446re")]
pub const SYSCLK_HZ: u32 = 168_000_000;

/// HSE mode: a 25 MHz crystal on the Black Pill.
#[cfg(feature = "stm32f411ce")]
const HSE: rcc::Hse = rcc::Hse {
    freq: Hertz(25_000_000),
    mode: rcc::HseMode::Oscillator,
};
/// HSE mode: the ST-LINK's 8 MHz MCO output, bypass mode.
#[cfg(feature = "stm32f446re")]
const HSE: rcc::Hse = rcc::Hse {
    freq: Hertz(8_000_000),
    mode: rcc::HseMode::Bypass,
};

/// Polls of HSE ready at boot, each after a busy wait of at least 1 ms
/// (crystals start in a few ms; ST's HAL allows 100 ms). Beyond them the
/// board runs on the HSI. `cortex_m::asm::delay` waits *at least* its
/// cycle count, not exactly: the whole wait is at least 100 ms and
/// 0.3-0.4 s in practice (issue 21), while the outputs stay low.
pub const HSE_STARTUP_TIMEOUT_MS: u32 = 100;

/// Encoder input pulls. `Up` for open-collector encoders (add external
/// 2.2-4.7 kΩ pull-ups to 3.3 V, see book/src/how-to/wire-a-board.md). Set `None` for encoders
/// with 5 V push-pull outputs on the 5 V tolerant pins: an FT pin only
/// tolerates more than VDD + 0.3 V with its internal pulls disabled.
pub const ENCODER_PULL: Pull = Pull::Up;

/// Digital input filter of both encoder channels (TIMx_CCMR1 IC1F/IC2F):
/// fSAMPLING = fDTS/16, N = 8 consecutive equal samples.
///
/// fDTS = the timer kernel clock (CKD = 0): 96 MHz on the F411 (APB1 48 MHz
/// ×2), 84 MHz on the F446 (APB1 42 MHz ×2). The filter rejects pulses
/// shorter than 16·8/96 MHz = 1.33 µs (1.52 µs on the F446) and delays
/// every edge by that much, equally on A and B, with ±1 sample
/// (0.17/0.19 µs) of jitter.
///
/// Edge spacing at the top speed: the example motor's no-load wheel speed
/// is 24 V / (0.05 V·s/rad × 12) = 40 rad/s; at 24 000 counts per wheel
/// revolution that is 40 × 24 000 / 2π = 152 800 counts/s, one ×4 edge
/// every 6.5 µs (alternating A and B; 13.1 µs between edges of one
/// channel). 1.33-1.52 µs is a quarter of the A-to-B spacing (half of it
/// with a 45° quadrature phase error), so the A/B order survives, while the
/// sub-µs ringing that motor PWM edges couple into encoder cables is
/// rejected. Faster encoders (more counts per second) need a shorter filter.
pub const ENCODER_INPUT_FILTER: FilterValue = FilterValue::FDTS_DIV16_N8;

/// Keep the independent watchdog counting while a debugger halts the core
/// (default), so a halted board resets within the watchdog timeout; the
/// `halt-freezes-watchdog` feature freezes it for bench debugging (the PWM
/// outputs are still forced low by TIM1 while halted, but ENABLE and DIR
/// keep their levels).
const FREEZE_WATCHDOG_ON_HALT: bool = cfg!(feature = "halt-freezes-watchdog");

/// Which oscillator the PLL runs from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockSource {
    /// The external clock ([`HSE`]), as designed.
    Hse,
    /// The internal 16 MHz RC (HSE did not start within
    /// [`HSE_STARTUP_TIMEOUT_MS`]): same SYSCLK, ±1 % accuracy at 25 °C and
    /// worse over temperature, not accurate enough for USB.
    HsiFallback,
}

/// Starts the HSE with a bounded wait (embassy's own wait has no timeout),
/// with raw RCC writes before embassy's clock setup; leaves it running when
/// it starts, off otherwise. Runs on the 16 MHz HSI (the reset clock).
fn start_hse() -> ClockSource {
    let rcc = pac::RCC;
    if rcc.cr().read().hserdy() {
        return ClockSource::Hse; // already running (started before a jump here)
    }
    // HSEBYP may only be written while HSE is off (the reset state; an HSE
    // that is on but not ready clocks nothing, so switching it off is safe).
    rcc.cr().modify(|w| w.set_hseon(false));
    rcc.cr()
        .modify(|w| w.set_hsebyp(HSE.mode == rcc::HseMode::Bypass));
    rcc.cr().modify(|w| w.set_hseon(true));
    for _ in 0..HSE_STARTUP_TIMEOUT_MS {
        if rcc.cr().read().hserdy() {
            return ClockSource::Hse;
        }
        cortex_m::asm::delay(rcc::HSI_FREQ.0 / 1000); // >= 1 ms at 16 MHz
    }
    rcc.cr().modify(|w| w.set_hseon(false));
    ClockSource::HsiFallback
}

/// Clock tree of the selected chip, from the HSE or (fallback) the HSI with
/// the same PLL output.
pub fn clock_config(source: ClockSource) -> Config {
    use rcc::*;
    let mut config = embassy_stm32::Config::default();
    let (hse, pll_src) = match source {
        ClockSource::Hse => (Some(HSE), PllSource::HSE),
        ClockSource::HsiFallback => (None, PllSource::HSI),
    };
    config.rcc.hse = hse;
    config.rcc.pll_src = pll_src;
    #[cfg(feature = "stm32f411ce")]
    {
        // 25 MHz HSE /25 (or 16 MHz HSI /16) = 1 MHz ×192 = 192 MHz VCO;
        // /2 = 96 MHz SYSCLK, /4 = 48 MHz (USB).
        config.rcc.pll = Some(Pll {
            prediv: match source {
                ClockSource::Hse => PllPreDiv::DIV25,
                ClockSource::HsiFallback => PllPreDiv::DIV16,
            },
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
        // 8 MHz MCO /4 (or 16 MHz HSI /8) = 2 MHz ×168 = 336 MHz VCO;
        // /2 = 168 MHz SYSCLK, Q /7 = 48 MHz for USB (CLK48SEL = PLL Q, the
        // reset value of DCKCFGR2). 180 MHz (VCO 360) has no integer Q for
        // 48 MHz; PLLSAI could supply it, but embassy-stm32 0.6 writes
        // PLLSAICFGR without PLLSAIM on the F446 (reset value 0 after its
        // whole-register write: an invalid divider) and names the CLK48 mux
        // input PLLSAI Q where RM0390 routes PLLSAI P, so it is not used.
        config.rcc.pll = Some(Pll {
            prediv: match source {
                ClockSource::Hse => PllPreDiv::DIV4,
                ClockSource::HsiFallback => PllPreDiv::DIV8,
            },
            mul: PllMul::MUL168,
            divp: Some(PllPDiv::DIV2),
            divq: Some(PllQDiv::DIV7),
            divr: None,
        });
        config.rcc.ahb_pre = AHBPrescaler::DIV1;
        config.rcc.apb1_pre = APBPrescaler::DIV4; // 42 MHz (max 45); timers 84 MHz
        config.rcc.apb2_pre = APBPrescaler::DIV2; // 84 MHz (max 90); TIM1 at 168 MHz
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

/// The motor driver (`motors.rs`): two H-bridge channels in the boot-time
/// bridge mode.
pub use crate::motors::HBridge;

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
    /// The oscillator the clocks run from.
    pub clock: ClockSource,
    /// Why the chip last reset (RCC_CSR at boot).
    pub reset_cause: wmr_protocol::ResetCause,
    /// `(right, left)` encoders.
    pub encoders: Encoders,
    /// Motor driver, disabled.
    pub motors: HBridge,
    /// Arm / disarm / reset button.
    pub button: ArmButton,
    /// Independent watchdog (configured, not yet started).
    pub watchdog: IndependentWatchdog<'static, IWDG>,
    /// The host link's port (USB OTG_FS on the F411, USART2 on the F446).
    pub link: Option<crate::link::LinkPeripherals>,
    /// The z-gyro ([`BoardGyro`]): with the `imu` feature the IMU task's
    /// newest sample (none until the IMU answered); without it none, and
    /// the estimator predicts with the wheels' yaw rate.
    pub gyro: BoardGyro,
    /// The IMU's bus and pins, taken by `main` to start the IMU task.
    #[cfg(feature = "imu")]
    pub imu: Option<crate::imu::ImuPeripherals>,
    /// External poses come over the host link only.
    pub pose_source: WheelOdometryOnly,
    /// The loop's watchdog setting while a robot-record write runs.
    pub stretch: Option<crate::store::WatchdogStretch>,
}

// The motor outputs driven low at the very start of the reset handler,
// before cortex-m-rt zeroes .bss and copies .data (about 1.5 ms on the
// 16 MHz reset clock, during which the pins would otherwise float):
// cortex-m-rt's `Reset` calls `__pre_init` first. Assembly, registers
// only (r0-r3, caller-saved), no RAM (none is initialised yet); the same
// writes as [`outputs_low_early`], which `main` repeats (idempotent). RCC
// AHB1ENR (0x4002_3830) GPIOAEN | GPIOBEN, read back; GPIOB (0x4002_0400)
// and GPIOA (0x4002_0000): BSRR resets every motor line of every bridge
// mode (motors.rs: PB0, PB1, PB12-PB15 = mask 0xF003; PA8, PA9), PUPDR
// pull-downs on all of them, MODER outputs on all of them.
core::arch::global_asm!(
    ".section .text.__pre_init,\"ax\",%progbits",
    ".global __pre_init",
    ".type __pre_init,%function",
    ".thumb_func",
    "__pre_init:",
    "movw r0, #0x3830",
    "movt r0, #0x4002",
    "ldr r1, [r0]",
    "orr r1, r1, #3",
    "str r1, [r0]",
    "ldr r1, [r0]",
    "movw r0, #0x0400",
    "movt r0, #0x4002",
    "movw r2, #0x0000",
    "movt r2, #0x4002",
    // BSRR: reset PB0, PB1, PB12-PB15; PA8, PA9.
    "movw r1, #0x0000",
    "movt r1, #0xF003",
    "str r1, [r0, #0x18]",
    "movw r1, #0x0000",
    "movt r1, #0x0300",
    "str r1, [r2, #0x18]",
    // PUPDR: pull-down (0b10) on the same pins.
    "ldr r1, [r0, #0x0C]",
    "movw r3, #0x000F",
    "movt r3, #0xFF00",
    "bic r1, r1, r3",
    "movw r3, #0x000A",
    "movt r3, #0xAA00",
    "orr r1, r1, r3",
    "str r1, [r0, #0x0C]",
    "ldr r1, [r2, #0x0C]",
    "bic r1, r1, #0xF0000",
    "orr r1, r1, #0xA0000",
    "str r1, [r2, #0x0C]",
    // MODER: general-purpose output (0b01) on the same pins.
    "ldr r1, [r0]",
    "movw r3, #0x000F",
    "movt r3, #0xFF00",
    "bic r1, r1, r3",
    "movw r3, #0x0005",
    "movt r3, #0x5500",
    "orr r1, r1, r3",
    "str r1, [r0]",
    "ldr r1, [r2]",
    "bic r1, r1, #0xF0000",
    "orr r1, r1, #0x50000",
    "str r1, [r2]",
    "bx lr",
    ".size __pre_init, . - __pre_init",
);

/// Drives the motor outputs low with raw register writes, before anything
/// else runs (call it first in `main`, before [`init`]): every motor line
/// of every bridge mode (motors.rs: ENABLE PB14, the direction / IN lines
/// PB0, PB1, PB12, PB13, PB15, PWM PA8, PA9) as push-pull outputs at 0,
/// with pull-downs for the instants when [`init`] hands PA8/PA9 (and, in
/// TwoPwm, PB13/PB0) to TIM1. Runs on the reset clock (HSI); embassy's
/// init only enables the GPIO clocks (it does not reset the ports), so
/// this state holds until [`init`] reconfigures the pins.
///
/// The `__pre_init` assembly above has done the same before the RAM
/// initialisation (Rust cannot run there: cortex-m-rt 0.7 deprecates
/// `#[pre_init]`, Rust before RAM initialisation is undefined behaviour);
/// this repeats it in Rust, idempotently. The pins float from reset to the
/// first instructions in any case, which is what the external pull-downs
/// are for.
pub fn outputs_low_early() {
    const PB: [usize; 6] = [0, 1, 12, 13, 14, 15];
    const PA: [usize; 2] = [8, 9];
    pac::RCC.ahb1enr().modify(|w| {
        w.set_gpioaen(true);
        w.set_gpioben(true);
    });
    let _ = pac::RCC.ahb1enr().read(); // clock on before the first port access
    pac::GPIOB
        .bsrr()
        .write_value(pac::gpio::regs::Bsrr(crate::motors::GPIOB_MOTOR_MASK << 16));
    pac::GPIOA.bsrr().write(|w| {
        for pin in PA {
            w.set_br(pin, true);
        }
    });
    pac::GPIOB.pupdr().modify(|w| {
        for pin in PB {
            w.set_pupdr(pin, pac::gpio::vals::Pupdr::PULL_DOWN);
        }
    });
    pac::GPIOA.pupdr().modify(|w| {
        for pin in PA {
            w.set_pupdr(pin, pac::gpio::vals::Pupdr::PULL_DOWN);
        }
    });
    pac::GPIOB.moder().modify(|w| {
        for pin in PB {
            w.set_moder(pin, pac::gpio::vals::Moder::OUTPUT);
        }
    });
    pac::GPIOA.moder().modify(|w| {
        for pin in PA {
            w.set_moder(pin, pac::gpio::vals::Moder::OUTPUT);
        }
    });
}

/// Starts the clocks (HSE with a bounded wait, else HSI), hands the flash
/// controller to `load_robot` and then binds the peripherals, the motor
/// outputs in the mode and frequency of the bridge `load_robot` returns
/// ([`HBridge::new`]; refused parameters leave them disabled). The robot
/// record is read before any motor timer runs, so a stored robot's
/// `[bridge]` of any mode applies at this boot (D115). Motor outputs stay
/// low throughout: through the load they are the push-pull GPIO outputs
/// at 0 of [`outputs_low_early`] (TIM1 not yet clocked), then ENABLE and
/// the GPIO lines low and the PWM channels enabled at duty 0 (driven low
/// by TIM1). Call [`outputs_low_early`] first.
pub async fn init<T, F>(load_robot: impl FnOnce(Peri<'static, FLASH>) -> F) -> (Board, T)
where
    F: core::future::Future<Output = (BridgeParams, T)>,
{
    let reset_cause = read_reset_cause();
    let clock = start_hse();
    let p = embassy_stm32::init(clock_config(clock));
    if clock == ClockSource::Hse {
        // Clock security system: an HSE failure at run time switches to the
        // HSI and raises an NMI, whose handler cuts the outputs.
        pac::RCC.cr().modify(|w| w.set_csson(true));
    }
    // The robot record (flash reads on the PLL clock, embassy's wait
    // states): the motor lines are still outputs_low_early's GPIO lows.
    let (bridge, loaded) = load_robot(p.FLASH).await;
    // Motor outputs in the bridge's mode, every line low (motors.rs).
    // `black_box`: the mode is a run-time value (the robot record's), so
    // every mode's code stays in the image.
    let motors = HBridge::new(
        p.TIM1,
        p.PA8,
        p.PA9,
        p.PB0,
        p.PB1,
        p.PB12,
        p.PB13,
        p.PB14,
        p.PB15,
        core::hint::black_box(bridge),
    );
    // Debugger halt: stop TIM1 (its outputs then go to the OSSI idle level,
    // low) and, unless built with `halt-freezes-watchdog`, keep the IWDG
    // running. DBGMCU is reset only by power-on, so write both bits.
    pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
    pac::DBGMCU
        .apb1fzr()
        .modify(|w| w.set_iwdg(FREEZE_WATCHDOG_ON_HALT));

    let encoders = (
        QeiEncoder(Qei::new(p.TIM3, p.PA6, p.PA7, qei_config())),
        QeiEncoder(Qei::new(p.TIM4, p.PB6, p.PB7, qei_config())),
    );
    for tim in [pac::TIM3, pac::TIM4] {
        tim.ccmr_input(0).modify(|w| {
            w.set_icf(0, ENCODER_INPUT_FILTER);
            w.set_icf(1, ENCODER_INPUT_FILTER);
        });
    }
    #[cfg(feature = "stm32f411ce")]
    let button = ArmButton(Input::new(p.PA0, Pull::Up));
    #[cfg(feature = "stm32f446re")]
    let button = ArmButton(Input::new(p.PC13, Pull::Up));

    let watchdog = IndependentWatchdog::new(p.IWDG, crate::config::WATCHDOG_TIMEOUT_US);
    // USB needs the 48 MHz clock within ±0.25 %: not on the HSI fallback.
    #[cfg(feature = "stm32f411ce")]
    let link = (clock == ClockSource::Hse).then_some(crate::link::LinkPeripherals {
        otg: p.USB_OTG_FS,
        dp: p.PA12,
        dm: p.PA11,
    });
    #[cfg(feature = "stm32f446re")]
    let link = Some(crate::link::LinkPeripherals {
        usart: p.USART2,
        tx: p.PA2,
        rx: p.PA3,
    });

    let board = Board {
        clock,
        reset_cause,
        encoders,
        motors,
        button,
        watchdog,
        stretch: None,
        link,
        #[cfg(feature = "imu")]
        gyro: crate::imu::gyro(),
        #[cfg(not(feature = "imu"))]
        gyro: controller_core::runtime::NoGyro,
        #[cfg(feature = "imu")]
        imu: Some(crate::imu::ImuPeripherals {
            i2c: p.I2C1,
            scl: p.PB8,
            sda: p.PB9,
            tx_dma: p.DMA1_CH6,
            rx_dma: p.DMA1_CH0,
        }),
        pose_source: WheelOdometryOnly,
    };
    (board, loaded)
}

/// The last reset's cause from the RCC_CSR flags (RM0383 §6.3.20 /
/// RM0390 §6.3.21; decoded by `robot_app::reset`), then clears them
/// (RMVF) so the next boot reports its own reset only. Read before
/// embassy's init, which touches the register (LSION).
fn read_reset_cause() -> wmr_protocol::ResetCause {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    robot_app::reset::from_stm32f4_csr(csr.0)
}

fn qei_config() -> qei::Config {
    qei::Config {
        ch1_pull: ENCODER_PULL,
        ch2_pull: ENCODER_PULL,
        ..qei::Config::default() // mode 3 (×4), full 16-bit range
    }
}

/// The application's view of the board (robot-app): the control task
/// drives everything through this.
impl robot_app::Board for Board {
    type Encoders = Encoders;
    type Motors = HBridge;
    type Gyro = BoardGyro;
    type PoseSource = WheelOdometryOnly;
    /// The status and trk/est lines only with `rtt-telemetry` (flash).
    const LOGS_STATUS: bool = cfg!(feature = "rtt-telemetry");

    fn io(&mut self) -> robot_app::BoardIo<'_, Encoders, HBridge, BoardGyro, WheelOdometryOnly> {
        robot_app::BoardIo {
            encoders: &mut self.encoders,
            motors: &mut self.motors,
            gyro: &mut self.gyro,
            pose_source: &mut self.pose_source,
        }
    }

    fn motors(&mut self) -> &mut HBridge {
        &mut self.motors
    }

    fn button_pressed(&mut self) -> bool {
        self.button.pressed()
    }

    fn start_watchdog(&mut self) {
        self.watchdog.unleash();
    }

    fn feed_watchdog(&mut self) {
        self.watchdog.pet();
    }

    /// The IWDG stretched to about 8 s for the flash write (store.rs).
    fn flash_write_begins(&mut self) {
        self.stretch = Some(crate::store::WatchdogStretch::begin());
    }

    fn flash_write_ends(&mut self) {
        if let Some(s) = self.stretch.take() {
            s.end();
        }
    }

    /// SYSRESETREQ: the chip boots with the motors off and reads the
    /// stored robot record.
    fn reboot(&mut self) {
        cortex_m::peripheral::SCB::sys_reset();
    }

    /// DWT CYCCNT (SYSCLK cycles), enabled in `main` with the
    /// `rtt-telemetry` feature (the only user of the statistics); 0 without.
    fn cycles(&mut self) -> u32 {
        #[cfg(feature = "rtt-telemetry")]
        {
            cortex_m::peripheral::DWT::cycle_count()
        }
        #[cfg(not(feature = "rtt-telemetry"))]
        {
            0
        }
    }

    fn event(&mut self, event: &robot_app::AppEvent<'_>) {
        crate::log::event(event, SYSCLK_HZ);
    }
}
