//! The emulated chip: Unicorn's Cortex-M4 core with the image in flash,
//! SRAM, the peripheral models behind MMIO hooks, exceptions entered and
//! returned by hand, time from the instruction count, and the run loop
//! that jumps time over sleeps (WFE/WFI) to the next peripheral event.
//!
//! Time: every executed instruction is one SYSCLK cycle (a fixed CPI of 1;
//! the real M4 takes more for loads, branches and flash wait states, so
//! emulated code is faster than on the chip and timing margins measured
//! here are upper bounds). Sleep lasts until the next event of a model.

use crate::bridge::BridgeMode;
use crate::elf::Image;
use crate::periph::flash::{STORE_BASE, STORE_SIZE};
use crate::periph::nvic::{exc, Nvic};
use crate::periph::rcc::{Rcc, ResetCause};
use crate::periph::timer::{Kind, Timer, Wave};
use crate::periph::{
    dbgmcu::Dbgmcu, flash::Flash, gpio, gpio::Port, iwdg::Iwdg, pwr::Pwr, scb::Scb, systick::Dwt,
    systick::SysTick, usart::Usart, PS_PER_S,
};
use crate::robot::{BridgeInputs, Robot};

mod bus;
mod exceptions;
mod i2c_bus;
mod link;
mod probe;
use bus::{mmio_read, mmio_write};
use exceptions::{deliverable, enter_exception, intr_hook, rd};
pub use probe::{CallStats, StepProbe};
use unicorn_engine::unicorn_const::{uc_error, Arch, HookType, MemType, Mode, Prot};
use unicorn_engine::{ArmCpuModel, RegisterARM, Unicorn};

/// The supported chips.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChipKind {
    /// STM32F446RE (Nucleo-64): HSE 8 MHz bypass, USART2 host link.
    F446re,
    /// STM32F411CE (Black Pill): HSE 25 MHz, USB OTG_FS host link.
    F411ce,
}

impl ChipKind {
    /// The arm button's pin (port index, pin) and name: PC13 on the
    /// Nucleo (B1), PA0 on the Black Pill (KEY) (firmware/src/board.rs).
    pub fn button(self) -> (usize, u32, &'static str) {
        match self {
            Self::F446re => (2, 13, "PC13"),
            Self::F411ce => (0, 0, "PA0"),
        }
    }

    /// HSE frequency \[Hz\].
    pub fn hse_hz(self) -> u64 {
        match self {
            Self::F446re => 8_000_000,
            Self::F411ce => 25_000_000,
        }
    }
    fn idcode(self) -> u32 {
        match self {
            Self::F446re => 0x1000_6421,
            Self::F411ce => 0x1000_6431,
        }
    }
    fn n_irq(self) -> usize {
        match self {
            Self::F446re => 97,
            Self::F411ce => 86,
        }
    }
    /// SRAM size \[B\].
    pub fn ram_size(self) -> u32 {
        128 * 1024
    }
    /// Flash size \[B\].
    pub fn flash_size(self) -> u32 {
        512 * 1024
    }
}

/// Flash base.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// SRAM base.
pub const RAM_BASE: u32 = 0x2000_0000;

/// IRQ numbers (RM0390 table 38; the same on the F411).
pub mod irq {
    /// TIM1 update.
    pub const TIM1_UP: usize = 25;
    /// TIM1 capture/compare.
    pub const TIM1_CC: usize = 27;
    /// TIM1 break.
    pub const TIM1_BRK: usize = 24;
    /// TIM3.
    pub const TIM3: usize = 29;
    /// TIM4.
    pub const TIM4: usize = 30;
    /// USART2.
    pub const USART2: usize = 38;
    /// TIM5 (embassy's time driver).
    pub const TIM5: usize = 50;
    /// USB OTG_FS global interrupt (RM0383 table 38).
    pub const OTG_FS: usize = 67;
    /// DMA1 stream 0 (I2C1_RX).
    pub const DMA1_STREAM0: usize = 11;
    /// DMA1 stream 6 (I2C1_TX).
    pub const DMA1_STREAM6: usize = 17;
    /// I2C1 event.
    pub const I2C1_EV: usize = 31;
    /// I2C1 error.
    pub const I2C1_ER: usize = 32;
}

/// Something the harness records.
#[derive(Clone, Debug)]
pub struct Event {
    /// Emulated time \[s\].
    pub t_s: f64,
    /// What happened.
    pub what: String,
}

/// Counters.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    /// Instructions executed (all boots).
    pub instructions: u64,
    /// Exceptions taken, by exception number.
    pub taken: std::collections::BTreeMap<usize, u64>,
    /// Boots (the first included).
    pub boots: u32,
    /// Resets: (time s, cause).
    pub resets: Vec<(f64, ResetCause)>,
    /// emu_start calls.
    pub slices: u64,
    /// Sleeps (WFE/WFI that waited).
    pub sleeps: u64,
    /// Watchdog feeds over all boots.
    pub feeds: u64,
    /// Exceptions taken between two instructions of an IT block (EPSR.IT
    /// nonzero at entry: stacked, cleared for the handler; D104).
    pub taken_in_it_block: u64,
    /// Lowest SP at an exception entry (after the frame) \[address\]:
    /// the deepest the main stack was seen.
    pub min_sp: u32,
}

/// Fault injection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// HardFault pended at once (as a fault escalated from a disabled
    /// configurable fault).
    HardFault,
    /// The next read of TIM3.CNT (the right encoder, read every tick) is a
    /// bus error: an imprecise BusFault (escalated to HardFault unless
    /// SHCSR.BUSFAULTENA), BFAR not valid.
    BusFaultOnEncoderRead,
}

/// The whole chip and its board: the state Unicorn's hooks reach.
pub struct Board {
    /// Chip.
    pub chip: ChipKind,
    /// Cycles (= instructions) since power-on.
    pub cycles: u64,
    base_cycles: u64,
    base_ps: u128,
    /// Core clock \[Hz\].
    pub sysclk_hz: u64,
    /// The block hook stops the run at this cycle count.
    deadline: u64,
    /// The block hook stops the run at the next block.
    stop_req: bool,
    /// A pending exception waits for PRIMASK/BASEPRI to drop: the block
    /// hook checks them.
    masked_pending: bool,
    /// First error (ends the run).
    pub error: Option<String>,
    /// The image's flash contents (instruction lengths).
    code: Vec<u8>,
    /// Candidate SEV addresses (hooked).
    /// Event register (SEV, exception entry/return).
    event_reg: bool,
    fp_stack: Vec<[u64; 17]>,
    /// Peripherals.
    pub rcc: Rcc,
    flash: Flash,
    pwr: Pwr,
    /// DBGMCU.
    pub dbgmcu: Dbgmcu,
    /// GPIO ports A-H.
    pub gpio: Vec<Port>,
    /// TIM1 (motor PWM).
    pub tim1: Timer,
    /// TIM3 (right encoder).
    pub tim3: Timer,
    /// TIM4 (left encoder).
    pub tim4: Timer,
    /// TIM5 (time driver).
    pub tim5: Timer,
    /// IWDG.
    pub iwdg: Iwdg,
    /// USART2 (host link on the F446).
    pub usart2: Usart,
    /// USB OTG_FS (host link on the F411).
    pub usb: crate::periph::otg_fs::OtgFs,
    /// The USB host on the F411's cable (`None` on the F446).
    pub usb_host: Option<crate::usb_host::UsbHost>,
    /// I2C1 (the IMU's bus on the `imu` images).
    pub i2c1: crate::periph::i2c::I2c,
    /// DMA1 (I2C1's streams 0 and 6).
    pub dma1: crate::periph::dma::Dma,
    /// The MPU-6050 on I2C1 (PB8 SCL, PB9 SDA); powered with the board,
    /// not reset with the MCU.
    pub mpu: crate::mpu6050::Mpu6050,
    /// NVIC.
    pub nvic: Nvic,
    /// SCB.
    pub scb: Scb,
    systick: SysTick,
    dwt: Dwt,
    /// The simulated robot.
    pub robot: Robot,
    /// Events.
    pub events: Vec<Event>,
    /// Counters.
    pub stats: Stats,
    /// Fault armed for the next TIM3.CNT read.
    fault_on_encoder_read: bool,
    /// When a fault was injected \[ps\] and the cycle count then.
    pub fault_at: Option<(u128, u64)>,
    /// From the injected fault to every motor pin low: (ps, instructions).
    pub cut_after_fault: Option<(u128, u64)>,
    /// Print events as they happen.
    pub verbose: bool,
    /// Time of the last idle (WFE) in this boot, if reached.
    pub idle_reached: bool,
    /// Watchdog started in this boot (the control loop runs).
    pub loop_started: bool,
    /// CSR as the current boot started.
    pub csr_at_boot: u32,
    /// Last motor-output state seen (for change events).
    pub last_bridge: BridgeInputs,
    /// The firmware's pin map at this boot's loop start when it is another
    /// bridge mode's than [`Self::bridge_mode`]'s (the image's compiled-in
    /// robot before a robot of the wired mode is pushed): its bridge must
    /// stay disabled until the next reset (`wiring_check`).
    pub foreign_pin_map: Option<BridgeMode>,
    /// How the harness's H-bridges are wired to the pins (the mode of the
    /// robot the image runs, stored or compiled in; firmware/src/motors.rs).
    pub bridge_mode: BridgeMode,
    /// Largest |armature voltage fraction| per wheel while driven since
    /// [`Self::peak_from_s`], and when (logged on every new peak).
    pub armature_peak: [(f64, f64); 2],
    /// The armature states' transients (`crate::bridge::TransientWatch`).
    pub transient_watch: crate::bridge::TransientWatch,
    /// Transients found (each logged as `bridge transient`).
    pub bridge_transients: u32,
    /// When the host program last wrote to the link \[ps\] (the `motors
    /// off` event says how long before: the link-silence stop's latency).
    pub last_host_byte_ps: Option<u128>,
    /// Peaks count from this emulated time on \[s\] (`--peak-from`).
    pub peak_from_s: f64,
    /// Unmodelled USB: the F411 reached OTG_FS.
    pub usb_reached: Option<f64>,
    /// Address of the last unmodelled access (for the F411 USB stop).
    pub unmodelled_addr: Option<u32>,
    /// The start addresses of the last [`TRACE_BLOCKS`] translation blocks
    /// executed (a ring; [`Self::trace_dump`] after a failure).
    trace: Vec<u32>,
    trace_n: usize,
    /// The last [`TRACE_EXCEPTIONS`] exception entries and returns.
    exc_trace: std::collections::VecDeque<String>,
    /// The loop has just started (the watchdog's first start this boot):
    /// the run loop takes the boot's stack high-water mark and paints the
    /// stack below SP again.
    repaint_stack: bool,
    /// CPU stall a flash operation asked for, not yet applied \[ps\].
    flash_stall_ps: u128,
    /// Instructions per call of the control step (`Controller::step`).
    pub step_probe: StepProbe,
}

/// Blocks kept in the failure trace.
pub const TRACE_BLOCKS: usize = 64;
/// Exception entries/returns kept in the failure trace.
pub const TRACE_EXCEPTIONS: usize = 24;

fn bad(uc: &mut Unicorn<Board>, msg: String) {
    let d = uc.get_data_mut();
    if d.error.is_none() {
        d.error = Some(msg);
    }
    d.stop_req = true;
    let _ = uc.emu_stop();
}

impl Board {
    fn new(chip: ChipKind, code: Vec<u8>) -> Self {
        let rcc = Rcc::new(Some(chip.hse_hz()));
        Self {
            chip,
            cycles: 0,
            base_cycles: 0,
            base_ps: 0,
            sysclk_hz: crate::periph::rcc::HSI_HZ,
            deadline: 0,
            stop_req: false,
            masked_pending: false,
            error: None,
            code,
            event_reg: false,
            fp_stack: Vec::new(),
            rcc,
            flash: Flash::default(),
            pwr: Pwr::default(),
            dbgmcu: Dbgmcu::new(chip.idcode()),
            gpio: "ABCDEFGH".chars().map(Port::new).collect(),
            tim1: Timer::new("TIM1", Kind::Advanced, 16_000_000),
            tim3: Timer::new("TIM3", Kind::General, 16_000_000),
            tim4: Timer::new("TIM4", Kind::General, 16_000_000),
            tim5: Timer::new("TIM5", Kind::General, 16_000_000),
            iwdg: Iwdg::new(),
            usart2: Usart::new("USART2", 16_000_000),
            usb: crate::periph::otg_fs::OtgFs::new(),
            usb_host: (chip == ChipKind::F411ce).then(crate::usb_host::UsbHost::new),
            i2c1: crate::periph::i2c::I2c::new(16_000_000),
            dma1: crate::periph::dma::Dma::default(),
            mpu: crate::mpu6050::Mpu6050::new(2, false),
            nvic: Nvic::new(chip.n_irq()),
            scb: Scb::default(),
            systick: SysTick::default(),
            dwt: Dwt::default(),
            robot: Robot::new(),
            events: Vec::new(),
            stats: Stats::default(),
            fault_on_encoder_read: false,
            fault_at: None,
            cut_after_fault: None,
            verbose: false,
            idle_reached: false,
            loop_started: false,
            csr_at_boot: 0,
            last_bridge: BridgeInputs::default(),
            foreign_pin_map: None,
            bridge_mode: BridgeMode::PwmDir,
            armature_peak: [(0.0, 0.0); 2],
            transient_watch: Default::default(),
            bridge_transients: 0,
            last_host_byte_ps: None,
            peak_from_s: 0.0,
            usb_reached: None,
            unmodelled_addr: None,
            trace: vec![0; TRACE_BLOCKS],
            trace_n: 0,
            exc_trace: std::collections::VecDeque::new(),
            repaint_stack: false,
            flash_stall_ps: 0,
            step_probe: StepProbe::default(),
        }
    }

    /// A program or erase just started: the CPU stalls for its duration
    /// (every flash read waits while the array is busy); the run loop
    /// applies it at the next block.
    fn flash_stall(&mut self) {
        let ps = self.flash.take_stall_ps();
        if ps > 0 {
            if ps >= 1_000_000_000 {
                let ms = ps as f64 * 1e-9;
                let n = self.flash.erases;
                self.event(format!(
                    "flash: sector erase {n} started, CPU stalled {ms:.1} ms (flash reads wait while BSY)"
                ));
            }
            self.flash_stall_ps += ps;
            self.stop_req = true;
        }
    }

    /// The flash model (the store's sectors, erase and program counts).
    pub fn flash(&mut self) -> &mut Flash {
        &mut self.flash
    }

    fn exc_log(&mut self, what: String) {
        if self.exc_trace.len() == TRACE_EXCEPTIONS {
            self.exc_trace.pop_front();
        }
        let t = self.now_s();
        self.exc_trace.push_back(format!("t={t:.6} {what}"));
    }

    /// The last blocks executed (oldest first) and the last exception
    /// entries and returns: what led to a failure.
    pub fn trace_dump(&self) -> String {
        let n = self.trace_n.min(TRACE_BLOCKS);
        let mut s = format!("last {n} blocks (oldest first):");
        for k in 0..n {
            let i = (self.trace_n - n + k) % TRACE_BLOCKS;
            if k % 8 == 0 {
                s += "\n   ";
            }
            s += &format!(" {:08X}", self.trace[i]);
        }
        s += &format!("\nlast {} exception entries/returns:", self.exc_trace.len());
        for e in &self.exc_trace {
            s += "\n    ";
            s += e;
        }
        s
    }

    /// Emulated time \[ps\].
    pub fn now_ps(&self) -> u128 {
        self.base_ps + (self.cycles - self.base_cycles) as u128 * PS_PER_S / self.sysclk_hz as u128
    }

    /// Emulated time \[s\].
    pub fn now_s(&self) -> f64 {
        self.now_ps() as f64 * 1e-12
    }

    /// The cycle count at which `ps` is reached.
    fn cycles_at(&self, ps: u128) -> u64 {
        if ps <= self.base_ps {
            return self.base_cycles;
        }
        let d = (ps - self.base_ps) * self.sysclk_hz as u128;
        self.base_cycles + d.div_ceil(PS_PER_S) as u64
    }

    /// Records an event.
    pub fn event(&mut self, what: String) {
        let t_s = self.now_s();
        if self.verbose {
            eprintln!("[stm32-emu t={t_s:10.6} s] {what}");
        }
        self.events.push(Event { t_s, what });
    }

    fn clocks_changed(&mut self) -> Result<(), String> {
        let c = self.rcc.clocks()?;
        let now = self.now_ps();
        if c.sysclk_hz != self.sysclk_hz {
            self.base_ps = now;
            self.base_cycles = self.cycles;
            self.sysclk_hz = c.sysclk_hz;
        }
        self.tim1.set_clock(now, c.timclk_apb2_hz);
        for t in [&mut self.tim3, &mut self.tim4, &mut self.tim5] {
            t.set_clock(now, c.timclk_apb1_hz);
        }
        self.usart2.set_clock(c.pclk1_hz);
        self.i2c1.set_clock(c.pclk1_hz);
        Ok(())
    }

    /// A motor pin's waveform: a GPIO output's level, TIM1 channel `ch`'s
    /// output (`complementary`: OCxN) when the pin is on AF1, low
    /// otherwise (input, analog, another AF: the board's pull-down).
    fn pin_wave(&self, port: usize, pin: u32, tim: Option<(usize, bool)>) -> Result<Wave, String> {
        let g = &self.gpio[port];
        Ok(match (g.mode(pin), tim) {
            (gpio::Mode::Output, _) => Wave::Level(g.odr_bit(pin)),
            (gpio::Mode::Alternate(1), Some((ch, n))) => self.tim1.waveform(ch, n, 0)?,
            _ => Wave::Level(false),
        })
    }

    /// The H-bridge inputs from the pins (firmware/src/motors.rs): PA8/PA9
    /// (TIM1 CH1/CH2: PWM, or TwoPwm's IN1), PB12/PB13 (DIR, or
    /// PwmIn1In2's IN1; PB13 is TwoPwm's right IN2 = TIM1 CH1N), PB0
    /// (TwoPwm's left IN2 = TIM1 CH2N), PB15/PB1 (PwmIn1In2's IN2), PB14
    /// ENABLE; the armature voltage through the model of
    /// [`Self::bridge_mode`] ([`crate::bridge::armature`]).
    pub fn bridge(&self) -> Result<BridgeInputs, String> {
        let pa = [
            self.pin_wave(0, 8, Some((0, false)))?,
            self.pin_wave(0, 9, Some((1, false)))?,
        ];
        let pb = |pin: u32, tim| self.pin_wave(1, pin, tim);
        let (pb0, pb1) = (pb(0, Some((1, true)))?, pb(1, None)?);
        let (pb12, pb13) = (pb(12, None)?, pb(13, Some((0, true)))?);
        let (pb14, pb15) = (pb(14, None)?, pb(15, None)?);
        let enable = pb14 == Wave::Level(true);
        let (second, third) = match self.bridge_mode {
            BridgeMode::PwmDir | BridgeMode::PwmIn1In2 => ([pb12, pb13], [pb15, pb1]),
            BridgeMode::TwoPwm => ([pb13, pb0], [Wave::Level(false); 2]),
        };
        let armature = [0, 1]
            .map(|i| crate::bridge::armature(self.bridge_mode, pa[i], second[i], third[i], enable));
        let high = |w: Wave| !matches!(w, Wave::Released | Wave::Level(false));
        let mut high_lines = 0u16;
        for (bit, w) in [
            (0, pb0),
            (1, pb1),
            (12, pb12),
            (13, pb13),
            (14, pb14),
            (15, pb15),
            (8, pa[0]),
            (9, pa[1]),
        ] {
            if high(w) {
                high_lines |= 1 << bit;
            }
        }
        let pwm = pa.map(|w| match w {
            Wave::Pwm { from, to, period } => (to - from, period),
            Wave::Level(true) => (1, 1),
            _ => (0, 1),
        });
        Ok(BridgeInputs {
            armature,
            pwm,
            high_lines,
            enable,
        })
    }

    /// The pins and timers the harness wires to the robot (firmware/src/
    /// board.rs) as the firmware configured them when its loop starts: a
    /// changed pin map fails the run instead of leaving the robot unwired.
    /// A complete pin map of another bridge mode (an image whose
    /// compiled-in robot has another mode, before the robot of the wired
    /// mode is pushed and booted) is accepted as [`Self::foreign_pin_map`]:
    /// the run fails if the firmware then enables the bridge
    /// ([`Self::foreign_enable_check`]) before the next reset.
    fn wiring_check(&mut self) -> Result<(), String> {
        self.foreign_pin_map = None;
        let Err(e) = self.pin_map_check(self.bridge_mode) else {
            return Ok(());
        };
        let others: Vec<BridgeMode> = [
            BridgeMode::PwmDir,
            BridgeMode::TwoPwm,
            BridgeMode::PwmIn1In2,
        ]
        .into_iter()
        .filter(|&m| m != self.bridge_mode && self.pin_map_check(m).is_ok())
        .collect();
        match others.first() {
            Some(&m) => {
                self.foreign_pin_map = Some(m);
                let names: Vec<String> = others.iter().map(|m| format!("{m:?}")).collect();
                self.event(format!(
                    "board wiring ({:?}): the firmware's pin map is {}'s; its bridge must stay disabled until the next reset",
                    self.bridge_mode,
                    names.join(" / ")
                ));
                Ok(())
            }
            None => Err(e),
        }
    }

    /// Fails when the bridge is enabled while the firmware's pin map is
    /// another mode's than the wiring's ([`Self::foreign_pin_map`]).
    fn foreign_enable_check(&self, b: &BridgeInputs) -> Result<(), String> {
        match self.foreign_pin_map {
            Some(m) if b.enable => Err(format!(
                "board wiring ({:?}): the firmware enabled the bridge with {m:?}'s pin map",
                self.bridge_mode
            )),
            _ => Ok(()),
        }
    }

    /// [`Self::wiring_check`] against the pin map of `mode`.
    fn pin_map_check(&self, mode: BridgeMode) -> Result<(), String> {
        use gpio::Mode::{Alternate, Output};
        let two = mode == BridgeMode::TwoPwm;
        let want: [(usize, u32, gpio::Mode, &str); 12] = [
            (0, 8, Alternate(1), "PA8 right PWM / IN1 (TIM1_CH1, AF1)"),
            (0, 9, Alternate(1), "PA9 left PWM / IN1 (TIM1_CH2, AF1)"),
            (0, 6, Alternate(2), "PA6 right encoder A (TIM3_CH1, AF2)"),
            (0, 7, Alternate(2), "PA7 right encoder B (TIM3_CH2, AF2)"),
            (1, 6, Alternate(2), "PB6 left encoder A (TIM4_CH1, AF2)"),
            (1, 7, Alternate(2), "PB7 left encoder B (TIM4_CH2, AF2)"),
            (1, 12, Output, "PB12 right DIR / IN1 (output)"),
            if two {
                (1, 13, Alternate(1), "PB13 right IN2 (TIM1_CH1N, AF1)")
            } else {
                (1, 13, Output, "PB13 left DIR / IN1 (output)")
            },
            if two {
                (1, 0, Alternate(1), "PB0 left IN2 (TIM1_CH2N, AF1)")
            } else {
                (1, 0, Output, "PB0 (unused, output low)")
            },
            (1, 1, Output, "PB1 left IN2 / unused (output)"),
            (1, 15, Output, "PB15 right IN2 / unused (output)"),
            (1, 14, Output, "PB14 ENABLE (output)"),
        ];
        for (port, pin, mode, what) in want {
            let got = self.gpio[port].mode(pin);
            if got != mode {
                return Err(format!(
                    "board wiring ({mode:?}): {what} expected, the firmware set {got:?}: the harness's robot would be unwired (update stm32-emu's pin map, or run with the image's --bridge)"
                ));
            }
        }
        Ok(())
    }

    /// Advances the robot to now with the bridge as it is.
    fn sync_robot(&mut self) -> Result<(), String> {
        let b = self.bridge()?;
        self.foreign_enable_check(&b)?;
        let now = self.now_ps();
        self.robot.advance(now, &b)?;
        if let (Some((t, c)), None) = (self.fault_at, self.cut_after_fault) {
            if b.all_low() {
                self.cut_after_fault = Some((now - t, self.cycles - c));
            }
        }
        if b != self.last_bridge {
            if b.armature != self.last_bridge.armature {
                let u = b.armature.map(|a| a.unwrap_or(0.0));
                for t in self.transient_watch.change(now, u) {
                    self.bridge_transients += 1;
                    self.event(format!(
                        "bridge transient {}: {:+.4} of the supply for {:.3} us at {:.6} s, between the stable {:+.4} and {:+.4} (an ordering of the motor writes)",
                        ["right", "left"][t.wheel],
                        t.armature,
                        t.len_ps as f64 * 1e-6,
                        t.at_ps as f64 * 1e-12,
                        t.before,
                        t.after
                    ));
                }
            }
            let was_off = self.last_bridge.motors_off();
            self.last_bridge = b;
            if b.motors_off() != was_off {
                let u = |a: Option<f64>| a.map_or("coast".to_string(), |u| format!("{u:+.3}"));
                let host = match (b.motors_off(), self.last_host_byte_ps) {
                    (true, Some(t)) => format!(
                        "; the host's last byte {:.1} ms before",
                        (now - t) as f64 * 1e-9
                    ),
                    _ => String::new(),
                };
                self.event(format!(
                    "motors {}: ENABLE {} lines 0x{:04X} PWM {}/{} of {} armature {}/{} of the supply{host}",
                    if b.motors_off() { "off" } else { "driven" },
                    b.enable as u8,
                    b.high_lines,
                    b.pwm[0].0,
                    b.pwm[1].0,
                    b.pwm[0].1,
                    u(b.armature[0]),
                    u(b.armature[1])
                ));
            }
            if self.now_s() >= self.peak_from_s {
                for i in 0..2 {
                    let u = b.armature[i].unwrap_or(0.0);
                    if u.abs() > self.armature_peak[i].0.abs() {
                        self.armature_peak[i] = (u, self.now_s());
                        self.event(format!(
                            "armature peak {}: {u:+.4} of the supply",
                            ["right", "left"][i]
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    fn encoder_pos(&mut self) -> Result<[u16; 2], String> {
        self.sync_robot()?;
        Ok(self.robot.encoder_counts())
    }

    /// Updates the NVIC's device interrupt lines from the models.
    fn update_lines(&mut self) {
        let now = self.now_ps();
        for t in [
            &mut self.tim1,
            &mut self.tim3,
            &mut self.tim4,
            &mut self.tim5,
        ] {
            t.sync(now);
        }
        self.usart2.sync(now);
        let (u, c, b) = self.tim1.irq_lines();
        self.nvic.set_line(irq::TIM1_UP, u);
        self.nvic.set_line(irq::TIM1_CC, c);
        self.nvic.set_line(irq::TIM1_BRK, b);
        for (t, n) in [
            (&self.tim3, irq::TIM3),
            (&self.tim4, irq::TIM4),
            (&self.tim5, irq::TIM5),
        ] {
            let (u, c, _) = t.irq_lines();
            self.nvic.set_line(n, u || c);
        }
        self.nvic.set_line(irq::USART2, self.usart2.irq());
        if self.usb_host.is_some() {
            self.nvic.set_line(irq::OTG_FS, self.usb.irq());
        }
        self.nvic.set_line(irq::I2C1_EV, self.i2c1.irq_ev());
        self.nvic.set_line(irq::I2C1_ER, self.i2c1.irq_er());
        self.nvic.set_line(irq::DMA1_STREAM0, self.dma1.irq(0));
        self.nvic.set_line(irq::DMA1_STREAM6, self.dma1.irq(6));
        if let Some(c) = self.systick.next_irq_cycles() {
            if self.cycles >= c {
                let _ = self.systick.read(0x8, self.cycles);
                self.nvic.set_pending(exc::SYSTICK);
            }
        }
    }

    /// The next time a model changes by itself \[ps\].
    fn next_event_ps(&self) -> Option<u128> {
        let mut t: Option<u128> = None;
        let mut add = |x: Option<u128>| {
            if let Some(x) = x {
                t = Some(t.map_or(x, |y| y.min(x)));
            }
        };
        for tm in [&self.tim1, &self.tim3, &self.tim4, &self.tim5] {
            add(tm.next_irq_ps());
        }
        add(self.usart2.next_event_ps());
        add(self.usb_host.as_ref().map(|h| h.next_event_ps()));
        add(self.iwdg.expiry_ps());
        add(self.i2c_next_event_ps());
        t
    }
}

/// The emulator.
pub struct Machine<'a> {
    /// Unicorn with the board as its data.
    pub uc: Unicorn<'a, Board>,
    image: Image,
    sleeping: bool,
    /// The CPU is held (the harness's stall) until this time \[ps\].
    stalled_until: Option<u128>,
    /// The painted stack `[_stack_end, _stack_start)`, if the image names it.
    stack: Option<(u32, u32)>,
    /// The current stall is a flash operation's: 1 an erase (its end is
    /// logged as such), 2 a word program (not logged); 0 the harness's.
    stall_is_flash: u8,
    /// The stack's high-water mark when the loop started, over all boots
    /// \[B\]; the paint is renewed below SP then, so
    /// [`Self::stack_usage`] measures the running firmware apart from its
    /// boot.
    boot_stack_bytes: u32,
}

/// The word the stack is painted with at power-on.
pub const STACK_PAINT: u32 = 0xA5C3_5A3C;

/// The main stack's size and high-water mark (`Machine::stack_usage`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StackUsage {
    /// `_stack_start - _stack_end` \[B\].
    pub size_bytes: u32,
    /// Deepest use seen since the loop started (the boot's use is
    /// `boot_bytes`) \[B\]; before the loop starts, since power-on.
    pub used_bytes: u32,
    /// Deepest use from reset to the loop's start, over all boots \[B\].
    pub boot_bytes: u32,
}

/// Thumb instructions in `[addr, addr + size)` of the flash image.
fn count_insns(code: &[u8], addr: u64, size: u32) -> u64 {
    let start = addr as i64 - FLASH_BASE as i64;
    if start < 0 || (start as usize) >= code.len() {
        return (size as u64).div_ceil(2).max(1);
    }
    let mut i = start as usize;
    let end = (i + size as usize).min(code.len());
    let mut n = 0;
    while i < end {
        let hw = u16::from_le_bytes([code[i], code[i + 1]]);
        i += if hw >> 11 >= 0b11101 { 4 } else { 2 };
        n += 1;
    }
    n.max(1)
}

impl<'a> Machine<'a> {
    /// The chip with `image` in flash, out of power-on reset.
    pub fn new(chip: ChipKind, image: Image) -> Result<Self, String> {
        let mut code = vec![0xFFu8; chip.flash_size() as usize];
        for (addr, data) in &image.segments {
            let a = *addr;
            if a >= FLASH_BASE && a + data.len() as u32 <= FLASH_BASE + chip.flash_size() {
                let o = (a - FLASH_BASE) as usize;
                code[o..o + data.len()].copy_from_slice(data);
            } else if !(a >= RAM_BASE && a < RAM_BASE + chip.ram_size()) {
                return Err(format!(
                    "segment at 0x{a:08X} ({} B) is outside flash and SRAM",
                    data.len()
                ));
            }
        }
        let ue = |e: uc_error| format!("unicorn: {e:?}");
        let mut uc = Unicorn::new_with_data(
            Arch::ARM,
            Mode::THUMB | Mode::MCLASS,
            Board::new(chip, code.clone()),
        )
        .map_err(ue)?;
        uc.ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)
            .map_err(ue)?;
        // Sectors 0-5 hold the program (memory.x: 256 KiB); sectors 6-7,
        // the robot store, are the flash model's (program/erase, MMIO).
        let program = STORE_BASE - FLASH_BASE;
        if code[program as usize..].iter().any(|&b| b != 0xFF) {
            return Err(format!(
                "the image has data at or above 0x{STORE_BASE:08X} (the robot store's sectors 6-7)"
            ));
        }
        uc.mem_map(FLASH_BASE as u64, program as u64, Prot::READ | Prot::EXEC)
            .map_err(ue)?;
        uc.mem_write(FLASH_BASE as u64, &code[..program as usize])
            .map_err(ue)?;
        uc.mmio_map(
            STORE_BASE as u64,
            STORE_SIZE as u64,
            Some(|uc: &mut Unicorn<Board>, off: u64, size: usize| -> u64 {
                mmio_read(uc, STORE_BASE + off as u32, size)
            }),
            Some(|uc: &mut Unicorn<Board>, off: u64, size: usize, v: u64| {
                mmio_write(uc, STORE_BASE + off as u32, size, v as u32)
            }),
        )
        .map_err(ue)?;
        uc.mem_map(RAM_BASE as u64, chip.ram_size() as u64, Prot::ALL)
            .map_err(ue)?;
        for (base, size) in [(0x4000_0000u64, 0x2000_0000u64), (0xE000_0000, 0x10_0000)] {
            uc.mmio_map(
                base,
                size,
                Some(
                    move |uc: &mut Unicorn<Board>, off: u64, size: usize| -> u64 {
                        mmio_read(uc, (base + off) as u32, size)
                    },
                ),
                Some(
                    move |uc: &mut Unicorn<Board>, off: u64, size: usize, v: u64| {
                        mmio_write(uc, (base + off) as u32, size, v as u32)
                    },
                ),
            )
            .map_err(ue)?;
        }
        uc.add_block_hook(1, 0, |uc, addr, size| {
            probe::on_block(uc, addr as u32);
            let d = uc.get_data_mut();
            let n = count_insns(&d.code, addr, size);
            d.trace[d.trace_n % TRACE_BLOCKS] = addr as u32;
            d.trace_n += 1;
            d.cycles += n;
            d.stats.instructions += n;
            let mut stop = d.stop_req || d.cycles >= d.deadline;
            if d.masked_pending && !stop {
                stop = deliverable(uc).is_some();
            }
            if stop {
                let _ = uc.emu_stop();
            }
        })
        .map_err(ue)?;
        uc.add_intr_hook(intr_hook).map_err(ue)?;
        // SEV: hooked at every halfword 0xBF40 of the image (only real
        // instruction starts ever fire).
        for (i, w) in code.chunks_exact(2).enumerate() {
            if w == [0x40, 0xBF] {
                let a = FLASH_BASE as u64 + 2 * i as u64;
                uc.add_code_hook(a, a, |uc, _, _| uc.get_data_mut().event_reg = true)
                    .map_err(ue)?;
            }
        }
        probe::install(&mut uc, &image).map_err(ue)?;
        uc.add_mem_hook(HookType::MEM_INVALID, 1, 0, |uc, t, addr, size, _v| {
            let pc = uc.reg_read(RegisterARM::PC).unwrap_or(0);
            let kind = match t {
                MemType::READ_UNMAPPED | MemType::READ_PROT => "read",
                MemType::WRITE_UNMAPPED | MemType::WRITE_PROT => "write",
                _ => "fetch",
            };
            bad(
                uc,
                format!(
                    "{kind} of {size} B at unmapped/protected 0x{addr:08X} (PC 0x{pc:08X}): not modelled"
                ),
            );
            false
        })
        .map_err(ue)?;
        let stack = match (image.symbol("_stack_end"), image.symbol("_stack_start")) {
            (Some(lo), Some(hi))
                if RAM_BASE <= lo && lo < hi && hi <= RAM_BASE + chip.ram_size() =>
            {
                // Painted once at power-on (SRAM keeps its contents over a
                // reset, as on the chip): cortex-m-rt initialises .data and
                // .bss only, so every word still holding the paint was never
                // written by the stack.
                let paint: Vec<u8> = (lo..hi)
                    .step_by(4)
                    .flat_map(|_| STACK_PAINT.to_le_bytes())
                    .collect();
                uc.mem_write(lo as u64, &paint).map_err(ue)?;
                Some((lo, hi))
            }
            _ => None,
        };
        let mut m = Self {
            uc,
            image,
            sleeping: false,
            stalled_until: None,
            stack,
            stall_is_flash: 0,
            boot_stack_bytes: 0,
        };
        m.reset(ResetCause::PowerOn)?;
        Ok(m)
    }

    /// The stack's size and its high-water mark \[B\]: from the top
    /// (`_stack_start`) down to the lowest word no longer holding the
    /// power-on paint (flip-link puts the stack below .data/.bss, growing
    /// down towards `_stack_end` at the bottom of SRAM). `None` without
    /// the symbols.
    pub fn stack_usage(&self) -> Option<StackUsage> {
        let (lo, hi) = self.stack?;
        let mut buf = vec![0u8; (hi - lo) as usize];
        self.uc.mem_read(lo as u64, &mut buf).ok()?;
        let untouched = buf
            .chunks_exact(4)
            .take_while(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) == STACK_PAINT)
            .count() as u32;
        Some(StackUsage {
            size_bytes: hi - lo,
            used_bytes: hi - lo - 4 * untouched,
            boot_bytes: self.boot_stack_bytes,
        })
    }

    /// At the loop's start: keeps the boot's high-water mark and paints
    /// the stack from its bottom to 256 B below SP again.
    fn repaint_stack(&mut self) -> Result<(), String> {
        let Some((lo, _)) = self.stack else {
            return Ok(());
        };
        if let Some(u) = self.stack_usage() {
            self.boot_stack_bytes = self.boot_stack_bytes.max(u.used_bytes);
        }
        let sp = rd(&self.uc, RegisterARM::SP) & !3;
        let top = sp.saturating_sub(256).max(lo);
        let paint: Vec<u8> = (lo..top)
            .step_by(4)
            .flat_map(|_| STACK_PAINT.to_le_bytes())
            .collect();
        self.uc
            .mem_write(lo as u64, &paint)
            .map_err(|e| format!("stack paint: {e:?}"))
    }

    /// The image's symbol `name`.
    pub fn symbol(&self, name: &str) -> Option<u32> {
        self.image.symbol(name)
    }

    /// The address of the first symbol starting with `prefix`.
    pub fn symbol_prefix(&self, prefix: &str) -> Option<u32> {
        self.image.symbol_prefix(prefix)
    }

    /// The board.
    pub fn board(&mut self) -> &mut Board {
        self.uc.get_data_mut()
    }

    /// A system reset of `cause`: core and peripherals to their reset
    /// state (SRAM, DBGMCU and the RCC reset flags kept), SP and PC from
    /// the vector table at the boot address (flash).
    pub fn reset(&mut self, cause: ResetCause) -> Result<(), String> {
        let ue = |e: uc_error| format!("unicorn: {e:?}");
        {
            let d = self.uc.get_data_mut();
            let chip = d.chip;
            if cause != ResetCause::PowerOn {
                let t = d.now_s();
                d.stats.resets.push((t, cause));
                d.event(format!("RESET ({cause:?})"));
            }
            d.rcc.reset(cause);
            if cause == ResetCause::PowerOn {
                d.rcc = Rcc::new(Some(chip.hse_hz()));
            }
            d.csr_at_boot = d.rcc.csr();
            let now = d.now_ps();
            d.base_ps = now;
            d.base_cycles = d.cycles;
            d.sysclk_hz = crate::periph::rcc::HSI_HZ;
            d.flash.reset();
            d.flash_stall_ps = 0;
            d.foreign_pin_map = None;
            d.pwr = Pwr::default();
            d.gpio = "ABCDEFGH".chars().map(Port::new).collect();
            d.tim1 = Timer::new("TIM1", Kind::Advanced, 16_000_000);
            d.tim3 = Timer::new("TIM3", Kind::General, 16_000_000);
            d.tim4 = Timer::new("TIM4", Kind::General, 16_000_000);
            d.tim5 = Timer::new("TIM5", Kind::General, 16_000_000);
            d.iwdg = Iwdg::new();
            let q = std::mem::take(&mut d.usart2.rx_queue);
            d.usart2 = Usart::new("USART2", 16_000_000);
            d.usart2.rx_queue = q;
            d.usb = crate::periph::otg_fs::OtgFs::new();
            let stats = d.i2c1.stats;
            d.i2c1 = crate::periph::i2c::I2c::new(16_000_000);
            d.i2c1.stats = stats;
            d.dma1 = crate::periph::dma::Dma::default();
            d.nvic = Nvic::new(chip.n_irq());
            d.scb = Scb::default();
            d.systick = SysTick::default();
            d.dwt = Dwt::default();
            d.fp_stack.clear();
            d.event_reg = false;
            d.stats.boots += 1;
            d.idle_reached = false;
            d.loop_started = false;
            let csr = d.csr_at_boot;
            let n = d.stats.boots;
            d.event(format!("boot {n}: RCC.CSR = 0x{csr:08X}"));
        }
        let mut vt = [0u8; 8];
        self.uc.mem_read(FLASH_BASE as u64, &mut vt).map_err(ue)?;
        let sp = u32::from_le_bytes(vt[0..4].try_into().unwrap_or_default());
        let pc = u32::from_le_bytes(vt[4..8].try_into().unwrap_or_default());
        if !(RAM_BASE..=RAM_BASE + self.uc.get_data().chip.ram_size()).contains(&sp) || pc & 1 == 0
        {
            return Err(format!(
                "vector table: initial SP 0x{sp:08X} / reset vector 0x{pc:08X} invalid"
            ));
        }
        for r in [
            RegisterARM::R0,
            RegisterARM::R1,
            RegisterARM::R2,
            RegisterARM::R3,
            RegisterARM::R4,
            RegisterARM::R5,
            RegisterARM::R6,
            RegisterARM::R7,
            RegisterARM::R8,
            RegisterARM::R9,
            RegisterARM::R10,
            RegisterARM::R11,
            RegisterARM::R12,
        ] {
            self.uc.reg_write(r, 0).map_err(ue)?;
        }
        self.uc.reg_write(RegisterARM::CONTROL, 0).map_err(ue)?;
        self.uc.reg_write(RegisterARM::PRIMASK, 0).map_err(ue)?;
        self.uc.reg_write(RegisterARM::BASEPRI, 0).map_err(ue)?;
        self.uc.reg_write(RegisterARM::FAULTMASK, 0).map_err(ue)?;
        self.uc.reg_write(RegisterARM::IPSR, 0).map_err(ue)?;
        self.uc.reg_write(RegisterARM::SP, sp as u64).map_err(ue)?;
        self.uc
            .reg_write(RegisterARM::LR, 0xFFFF_FFFF)
            .map_err(ue)?;
        self.uc.reg_write(RegisterARM::PC, pc as u64).map_err(ue)?;
        self.sleeping = false;
        self.stalled_until = None;
        Ok(())
    }

    /// Holds the CPU for `ps` from now (no instruction runs; time, the
    /// peripherals and the watchdog go on): the harness's stalled loop.
    pub fn stall(&mut self, ps: u128) {
        let now = self.uc.get_data().now_ps();
        self.stalled_until = Some(now + ps);
        let ms = ps as f64 * 1e-9;
        self.board()
            .event(format!("stall injected: CPU held for {ms:.1} ms"));
    }

    /// Injects a fault.
    pub fn inject(&mut self, f: Fault) {
        let d = self.board();
        match f {
            Fault::HardFault => {
                d.scb.hfsr |= 1 << 30;
                d.nvic.set_pending(exc::HARD_FAULT);
                d.fault_at = Some((d.now_ps(), d.cycles));
                d.event("fault injected: HardFault pended".into());
            }
            Fault::BusFaultOnEncoderRead => d.fault_on_encoder_read = true,
        }
    }

    /// Runs until emulated time `until_ps`; `on_poll` is called every
    /// `poll_ps` of emulated time (host I/O, pacing, the script).
    pub fn run_until(
        &mut self,
        until_ps: u128,
        poll_ps: u128,
        on_poll: &mut dyn FnMut(&mut Machine) -> Result<(), String>,
    ) -> Result<(), String> {
        let mut next_poll = self.uc.get_data().now_ps();
        loop {
            if let Some(e) = self.uc.get_data_mut().error.take() {
                return Err(e);
            }
            let now = self.uc.get_data().now_ps();
            if now >= until_ps {
                return Ok(());
            }
            if now >= next_poll {
                on_poll(self)?;
                next_poll = now + poll_ps;
                if let Some(e) = self.uc.get_data_mut().error.take() {
                    return Err(e);
                }
            }
            if std::mem::take(&mut self.uc.get_data_mut().repaint_stack) {
                self.repaint_stack()?;
            }
            let fs = std::mem::take(&mut self.uc.get_data_mut().flash_stall_ps);
            if fs > 0 {
                let now = self.uc.get_data().now_ps();
                let until = self.stalled_until.unwrap_or(now).max(now) + fs;
                self.stalled_until = Some(until);
                self.stall_is_flash = match (fs >= 1_000_000_000, self.stall_is_flash) {
                    (true, _) => 1,
                    (false, 0) => 2,
                    (false, k) => k,
                };
            }
            // Peripherals to now; the watchdog; SYSRESETREQ.
            {
                let d = self.uc.get_data_mut();
                d.sync_robot()?;
                d.sync_usb()?;
            }
            self.sync_i2c()?;
            {
                let d = self.uc.get_data_mut();
                d.update_lines();
                if d.iwdg.expiry_ps().is_some_and(|t| t <= now) {
                    d.event("IWDG expired".into());
                    self.reset(ResetCause::Iwdg)?;
                    continue;
                }
                if d.scb.reset_requested {
                    self.reset(ResetCause::Software)?;
                    continue;
                }
            }
            let deadline_ps = {
                let d = self.uc.get_data();
                let mut t = d
                    .next_event_ps()
                    .unwrap_or(u128::MAX)
                    .min(until_ps)
                    .min(next_poll);
                if let Some(s) = self.stalled_until {
                    t = t.min(s);
                }
                t
            };
            if let Some(s) = self.stalled_until {
                if now < s {
                    let d = self.uc.get_data_mut();
                    d.cycles = d.cycles.max(d.cycles_at(deadline_ps));
                    continue;
                }
                self.stalled_until = None;
                let flash = std::mem::take(&mut self.stall_is_flash);
                let d = self.board();
                match flash {
                    1 => d.event("flash: erase done, CPU runs again".into()),
                    2 => {}
                    _ => d.event("stall ends: CPU runs again".into()),
                }
            }
            // Exceptions.
            if let Some(e) = deliverable(&mut self.uc) {
                self.sleeping = false;
                enter_exception(&mut self.uc, e)?;
            } else if self.sleeping {
                // WFE/WFI wake on an exception that would preempt with
                // PRIMASK ignored (B1.5.19), or on any pending one with SEVONPEND.
                let basepri = self.uc.reg_read(RegisterARM::BASEPRI).unwrap_or(0) as u8;
                let d = self.uc.get_data();
                let wake = d.nvic.to_take(false, basepri, false).is_some()
                    || (d.scb.sevonpend() && d.nvic.highest_pending().is_some());
                if wake {
                    self.sleeping = false;
                } else {
                    let d = self.uc.get_data_mut();
                    if deadline_ps == u128::MAX {
                        return Err("the core sleeps with no event left to wake it".into());
                    }
                    d.cycles = d.cycles.max(d.cycles_at(deadline_ps));
                    continue;
                }
            }
            {
                let d = self.uc.get_data_mut();
                d.deadline = d.cycles_at(deadline_ps).max(d.cycles + 1);
                d.stop_req = false;
                d.masked_pending = d.nvic.highest_pending().is_some();
                d.stats.slices += 1;
            }
            let pc = self
                .uc
                .reg_read(RegisterARM::PC)
                .map_err(|e| format!("{e:?}"))?;
            let r = self.uc.emu_start(pc | 1, 0, 0, 0);
            if let Some(e) = self.uc.get_data_mut().error.take() {
                return Err(e);
            }
            match r {
                Ok(()) => {}
                Err(uc_error::INSN_INVALID) => self.invalid_insn()?,
                Err(e) => {
                    let pc = self.uc.reg_read(RegisterARM::PC).unwrap_or(0);
                    return Err(format!("emulation stopped: {e:?} at PC 0x{pc:08X}"));
                }
            }
        }
    }

    /// WFE/WFI (PC past them) sleep; UDF is a UsageFault (escalated to
    /// HardFault); anything else fails.
    fn invalid_insn(&mut self) -> Result<(), String> {
        let pc = self
            .uc
            .reg_read(RegisterARM::PC)
            .map_err(|e| format!("{e:?}"))? as u32;
        let hw = |a: u32| -> u16 {
            let mut b = [0u8; 2];
            let _ = self.uc.mem_read(a as u64, &mut b);
            u16::from_le_bytes(b)
        };
        let prev = hw(pc.wrapping_sub(2));
        let here = hw(pc);
        if prev == 0xBF20 || prev == 0xBF30 {
            let d = self.uc.get_data_mut();
            if !d.idle_reached {
                d.idle_reached = true;
                d.event(format!(
                    "executor idle reached ({} at 0x{:08X})",
                    if prev == 0xBF20 { "WFE" } else { "WFI" },
                    pc - 2
                ));
            }
            if prev == 0xBF20 && std::mem::take(&mut d.event_reg) {
                return Ok(()); // event register was set: WFE falls through
            }
            d.stats.sleeps += 1;
            self.sleeping = true;
            return Ok(());
        }
        if here >> 8 == 0xDE {
            // UDF: UNDEFINSTR UsageFault, escalated unless enabled.
            let d = self.uc.get_data_mut();
            d.scb.cfsr |= 1 << 16;
            if d.scb.shcsr & (1 << 18) != 0 {
                d.nvic.set_pending(exc::USAGE_FAULT);
            } else {
                d.scb.hfsr |= 1 << 30;
                d.nvic.set_pending(exc::HARD_FAULT);
            }
            d.event(format!("UDF at 0x{pc:08X}: UsageFault (UNDEFINSTR)"));
            // The faulting instruction is the return address (precise).
            return Ok(());
        }
        Err(format!(
            "invalid instruction at PC 0x{pc:08X} (0x{here:04X}; previous 0x{prev:04X})"
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unknown register fails with its address and name, never a zero;
    /// so does a modelled peripheral with its RCC clock off.
    #[test]
    fn unknown_registers_and_gated_clocks_fail() {
        let mut b = Board::new(ChipKind::F446re, vec![0xFF; 1024]);
        let e = b.read_word(0x4000_0024).unwrap_err();
        assert!(e.contains("TIM2"), "{e}");
        let e = b.write_word(0x5000_0010, 1, !0).unwrap_err(); // F446: OTG_FS not modelled
        assert!(e.contains("USB_OTG_FS") && e.contains("GRSTCTL"), "{e}");
        let e = b.read_word(0x4000_0C24).unwrap_err();
        assert!(e.contains("TIM5") && e.contains("clock off"), "{e}");
        b.write_word(0x4002_3840, 1 << 3, !0).unwrap(); // APB1ENR TIM5EN
        assert!(b.read_word(0x4000_0C24).is_ok());
        let e = b.read_word(0x4000_0C4C).unwrap_err();
        assert!(e.contains("DMAR"), "{e}");
        // I2C1 and DMA1: gated by I2C1EN (APB1ENR bit 21) and DMA1EN
        // (AHB1ENR bit 21); their unknown offsets fail.
        let e = b.read_word(0x4000_5400).unwrap_err();
        assert!(e.contains("I2C1") && e.contains("clock off"), "{e}");
        let e = b.read_word(0x4002_6000).unwrap_err();
        assert!(e.contains("DMA1") && e.contains("clock off"), "{e}");
        b.write_word(0x4002_3840, (1 << 3) | (1 << 21), !0).unwrap();
        b.write_word(0x4002_3830, 1 << 21, !0).unwrap();
        assert_eq!(b.read_word(0x4000_5420).unwrap(), 2, "TRISE resets to 2");
        assert!(b.read_word(0x4000_5428).is_err());
        assert_eq!(
            b.read_word(0x4002_6024).unwrap(),
            0x21,
            "S0FCR resets to 0x21"
        );
        assert!(b.read_word(0x4002_60D0).is_err());
        // START with PB8/PB9 not on AF4 open drain: the wiring is wrong.
        b.write_word(0x4000_5400, 1, !0).unwrap();
        let e = b.write_word(0x4000_5400, 1 | (1 << 8), !0).unwrap_err();
        assert!(e.contains("SCL PB8"), "{e}");
    }

    /// Pins at their reset state (PA8 an input) fail the wiring check by
    /// name; configured as board.rs does, they pass.
    /// Bus recovery through the GPIOs (UM10204 §3.1.16): with the MPU-6050
    /// holding SDA, PB9 as an open-drain output driven high reads low
    /// (wired-AND); each rising edge of PB8 as an output is one SCL clock,
    /// and SDA reads high after the clocks the chip needed.
    #[test]
    fn sda_held_reads_low_until_clocked_free() {
        let mut b = Board::new(ChipKind::F446re, vec![0xFF; 1024]);
        b.write_word(0x4002_3830, 1 << 1, !0).unwrap(); // GPIOBEN
        b.mpu.faults.stuck_sda = Some((0, 3));
        b.mpu.stop(crate::mpu6050::START_UP_PS);
        let gpiob = 0x4002_0400;
        // PB8, PB9: open drain, high, then outputs (as embassy's
        // OutputOpenDrain::new(Level::High): no edge on the lines).
        b.write_word(gpiob + 0x04, 3 << 8, !0).unwrap();
        b.write_word(gpiob + 0x18, 3 << 8, !0).unwrap();
        b.write_word(gpiob, (1 << 16) | (1 << 18), 0xF << 16)
            .unwrap();
        let sda = |b: &mut Board| b.read_word(gpiob + 0x10).unwrap() & (1 << 9) != 0;
        assert!(!sda(&mut b), "held low by the slave");
        for i in 0..3 {
            assert!(!sda(&mut b), "still held before clock {}", i + 1);
            b.write_word(gpiob + 0x18, 1 << (16 + 8), !0).unwrap(); // SCL low
            b.write_word(gpiob + 0x18, 1 << 8, !0).unwrap(); // SCL high
        }
        assert!(sda(&mut b), "released after 3 clocks");
        assert_eq!(b.mpu.stats.recovery_clocks, 3);
        // Output low from an input (the pulled-up line falls) and back
        // high is a clock too; staying an output high is none.
        b.mpu = {
            let mut m = crate::mpu6050::Mpu6050::new(2, false);
            m.faults.stuck_sda = Some((0, 2));
            m.stop(crate::mpu6050::START_UP_PS);
            m
        };
        b.write_word(gpiob + 0x18, 1 << 8, !0).unwrap();
        assert_eq!(b.mpu.stats.recovery_clocks, 0, "high to high: no clock");
        b.write_word(gpiob, 0, 3 << 16).unwrap(); // PB8 input: high (pull-up)
        b.write_word(gpiob + 0x18, 1 << (16 + 8), !0).unwrap(); // ODR low
        b.write_word(gpiob, 1 << 16, 3 << 16).unwrap(); // output: falls
        b.write_word(gpiob + 0x18, 1 << 8, !0).unwrap(); // rises
        assert_eq!(b.mpu.stats.recovery_clocks, 1);
    }

    #[test]
    fn wiring_check_names_the_pin() {
        let mut b = Board::new(ChipKind::F446re, vec![0xFF; 1024]);
        let e = b.wiring_check().unwrap_err();
        assert!(e.contains("PA8"), "{e}");
        b.write_word(0x4002_3830, 0b11, !0).unwrap(); // GPIOA/B clocks
                                                      // PA6-PA9 AF (MODER 10), AF2 on 6/7 and AF1 on 8/9.
        b.write_word(0x4002_0000, 0b10101010 << 12, 0xFF << 12)
            .unwrap();
        b.write_word(0x4002_0020, 0x22 << 24, 0xFF << 24).unwrap();
        b.write_word(0x4002_0024, 0x11, 0xFF).unwrap();
        // PB6/PB7 AF2; PB0, PB1, PB12-PB15 outputs (every bridge line).
        b.write_word(
            0x4002_0400,
            0b0101 | (0b1010 << 12) | (0x55 << 24),
            0xF | (0xF << 12) | (0xFF << 24),
        )
        .unwrap();
        b.write_word(0x4002_0420, 0x22 << 24, 0xFF << 24).unwrap();
        b.wiring_check().unwrap();
        assert_eq!(b.foreign_pin_map, None);
        // The TwoPwm harness wants PB13/PB0 on TIM1 CH1N/CH2N: its own map
        // fails by name, the GPIO map is PwmDir's complete map (an image of
        // another compiled-in mode before the push): accepted as foreign,
        // the bridge must then stay disabled.
        b.bridge_mode = BridgeMode::TwoPwm;
        let e = b.pin_map_check(BridgeMode::TwoPwm).unwrap_err();
        assert!(e.contains("PB13"), "{e}");
        b.wiring_check().unwrap();
        assert_eq!(b.foreign_pin_map, Some(BridgeMode::PwmDir));
        let mut inputs = BridgeInputs::default();
        b.foreign_enable_check(&inputs).unwrap();
        inputs.enable = true;
        let e = b.foreign_enable_check(&inputs).unwrap_err();
        assert!(
            e.contains("enabled the bridge with PwmDir's pin map"),
            "{e}"
        );
        b.write_word(0x4002_0400, (0b10 << 26) | 0b10, (0b11 << 26) | 0b11)
            .unwrap();
        b.write_word(0x4002_0424, 1 << 20, 0xF << 20).unwrap(); // AFRH PB13 = 1
        b.write_word(0x4002_0420, 1, 0xF).unwrap(); // AFRL PB0 = 1
        b.wiring_check().unwrap();
        assert_eq!(b.foreign_pin_map, None);
        b.foreign_enable_check(&inputs).unwrap();
        b.bridge_mode = BridgeMode::PwmDir;
        assert!(b
            .pin_map_check(BridgeMode::PwmDir)
            .unwrap_err()
            .contains("PB13"));
        b.wiring_check().unwrap();
        assert_eq!(b.foreign_pin_map, Some(BridgeMode::TwoPwm));
        // A map of no mode (PA8 back to an input) still fails by name.
        b.write_word(0x4002_0000, 0, 0b11 << 16).unwrap();
        assert!(b.wiring_check().unwrap_err().contains("PA8"));
    }

    /// An exception taken between two instructions of an IT block (the
    /// block split over a 1 KiB translation page: Unicorn stops at the
    /// page's boundary like at any block start) enters its handler with
    /// EPSR.IT cleared (ARMv7-M B1.5.6: ExceptionTaken sets IT to 0) and
    /// returns to the rest of the block with the IT state it stacked.
    /// Without the clearing the handler's first instruction runs as the
    /// IT block's next slot: here a false one, so it is skipped (a skipped
    /// `push` in a real handler returns through a stack word: the CI
    /// crash "invalid instruction at PC 0x2001B190", PC in the stack).
    #[test]
    fn exception_inside_an_it_block_clears_it_in_the_handler() {
        let mut code = vec![0xFFu8; 0x600];
        let mut put = |at: usize, hw: &[u16]| {
            for (k, h) in hw.iter().enumerate() {
                code[at + 2 * k..at + 2 * k + 2].copy_from_slice(&h.to_le_bytes());
            }
        };
        // Vectors: SP, Reset at 0x3F6, SysTick (15) at 0x500.
        put(0, &[0x1000, 0x2000, 0x03F7, 0x0800]);
        put(15 * 4, &[0x0501, 0x0800]);
        put(
            0x3F6,
            &[
                0x4280, // cmp r0, r0 (Z = 1)
                0xBF00, // nop
                0xBF00, // nop
                0xBF0C, // ite eq
                0x4612, // (then, eq: taken) mov r2, r2; the page ends here
                0x2377, // 0x400 (else, ne: skipped) mov r3, #0x77
                0xE7FE, // b .
            ],
        );
        put(
            0x500,
            &[
                0xF04F, 0x0455, // mov.w r4, #0x55 (r4: not in the frame)
                0x4770, // bx lr (EXC_RETURN)
            ],
        );
        let image = Image {
            segments: vec![(FLASH_BASE, code)],
            symbols: vec![],
        };
        let mut m = Machine::new(ChipKind::F446re, image).unwrap();
        // Until the first block (5 instructions) has run: the run stops at
        // the next block's start, 0x400, inside the IT block.
        let cycle_ps = PS_PER_S / crate::periph::rcc::HSI_HZ as u128;
        m.run_until(6 * cycle_ps, PS_PER_S / 1000, &mut |_| Ok(()))
            .unwrap();
        assert_eq!(
            m.uc.reg_read(RegisterARM::PC).unwrap(),
            0x0800_0400,
            "the run did not stop inside the IT block"
        );
        assert_ne!(
            m.uc.reg_read(RegisterARM::XPSR).unwrap() & 0x0600_FC00,
            0,
            "no IT state at the stop"
        );
        m.board().nvic.set_pending(exc::SYSTICK);
        m.run_until(100 * cycle_ps, PS_PER_S / 1000, &mut |_| Ok(()))
            .unwrap();
        assert_eq!(m.board().stats.taken.get(&exc::SYSTICK), Some(&1));
        assert_eq!(
            m.uc.reg_read(RegisterARM::R4).unwrap(),
            0x55,
            "the handler's first instruction ran as the IT block's (false) else slot"
        );
        assert_eq!(
            m.uc.reg_read(RegisterARM::R3).unwrap(),
            0,
            "the IT block's else slot ran after the return: its IT state was lost"
        );
    }

    /// Thumb-2 lengths: 0b11101/0b11110/0b11111 prefixes are 32-bit.
    #[test]
    fn instruction_lengths() {
        // mov r0,#1 (16) ; bl (32: F000 F800) ; nop (16)
        let mut code = vec![0u8; 16];
        code[0..2].copy_from_slice(&0x2001u16.to_le_bytes());
        code[2..4].copy_from_slice(&0xF000u16.to_le_bytes());
        code[4..6].copy_from_slice(&0xF800u16.to_le_bytes());
        code[6..8].copy_from_slice(&0xBF00u16.to_le_bytes());
        assert_eq!(count_insns(&code, FLASH_BASE as u64, 8), 3);
    }
}
