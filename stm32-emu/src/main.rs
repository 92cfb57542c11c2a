//! `stm32-emu`: runs the unmodified STM32 release image (firmware/ci.sh's
//! ELF) on Unicorn's Cortex-M4 with the peripheral models, closed through
//! sim-robot, with USART2 on a pseudo-terminal for `wmr`.
//!
//! ```text
//! stm32-emu --elf firmware/target/ci-stm32f446re/thumbv7em-none-eabihf/release/firmware \
//!           [--chip f446re|f411ce] [--pty] [--realtime] [--seconds S]
//!           [--press AT_S] [--stall AT_S:MS] [--fault hardfault@AT_S|busfault@AT_S]
//!           [--bridge pwm-dir|two-pwm|pwm-in1-in2] [--peak-from S]
//!           [--robot FILE] [--flash-timing typ|max]
//!           [--flash-aged | --flash-robot FILE [--flash-pwm-hz N]]
//!           [--summary FILE] [--quiet]
//! ```
//! `--bridge` says how the harness's H-bridges are wired (the `[bridge]`
//! mode of the robot the image runs: the stored robot's, else the
//! compiled-in one's, `BRIDGE_MODE`; default `--robot`'s mode, else
//! pwm-dir); the largest armature voltage per wheel
//! from `--peak-from` on is logged (`armature peak`) and in the summary.
//! `--robot FILE` makes the simulated robot that robot file's (body,
//! friction, motors, encoders, motor directions; the bridge wiring its
//! `[bridge]` mode unless `--bridge` says otherwise); without it the
//! firmware's compiled-in paper robot. `--flash-timing` takes the
//! datasheet's typical (default) or maximum program/erase times
//! (`periph::flash`); `--flash-aged` starts with the robot store's sectors
//! as the firmware's store code leaves them when the next save must erase
//! a sector (the `--robot` file's record, or the paper robot's, saved until
//! then); `--flash-robot FILE` starts with that robot file's record saved
//! once; `--flash-pwm-hz N` crafts it: its `bridge.pwm_frequency_hz`
//! replaced by N after robot-file's validation, with a valid CRC (a record
//! the firmware never writes; another tool could have flashed it).
//! With `--pty` the first line on stdout is the pty's path (as `hil-sim
//! device --pty` prints it) and the run goes on until killed or `--seconds`.
//! The summary (JSON, one line) goes to `--summary` or stdout at the end.

use std::io::{Read, Write};
use std::time::{Duration, Instant};
use stm32_emu::machine::{ChipKind, Fault, Machine};
use stm32_emu::periph::rcc::csr;

struct Args {
    elf: String,
    chip: ChipKind,
    pty: bool,
    realtime: bool,
    seconds: Option<f64>,
    press: Option<f64>,
    stall: Option<(f64, f64)>,
    fault: Option<(Fault, f64)>,
    summary: Option<String>,
    quiet: bool,
    bridge: Option<stm32_emu::bridge::BridgeMode>,
    peak_from: f64,
    robot: Option<robot_file::Robot>,
    flash_timing: stm32_emu::periph::flash::FlashTiming,
    flash_aged: bool,
    flash_robot: Option<(String, robot_file::Robot)>,
    flash_pwm_hz: Option<u32>,
    /// USB (F411): DTR low from AT for S seconds.
    usb_dtr_low: Option<(f64, f64)>,
    /// USB (F411): the host stops reading (no bulk IN tokens) from AT for S.
    usb_stop_reading: Option<(f64, f64)>,
    /// USB (F411): the cable out at AT for MS, then re-plugged.
    usb_unplug: Option<(f64, f64)>,
    /// USB (F411): a descriptor byte replaced on receipt by the host.
    usb_corrupt: Option<stm32_emu::usb_host::Corrupt>,
    /// The MPU-6050's injected faults.
    imu: stm32_emu::mpu6050::Faults,
}

/// Seconds to ps.
fn ps(s: f64) -> u128 {
    (s * PS) as u128
}

/// `AT:DURATION` (two numbers).
fn pair(v: &str, what: &str) -> Result<(f64, f64), String> {
    let (a, b) = v
        .split_once(':')
        .ok_or_else(|| format!("{what} {v}: expected AT_S:DURATION"))?;
    let (a, b) = (num(a, what)?, num(b, what)?);
    if !(a >= 0.0 && b > 0.0) {
        return Err(format!("{what} {v}: expected AT_S >= 0 and DURATION > 0"));
    }
    Ok((a, b))
}

fn usage() -> String {
    "usage: stm32-emu --elf FILE [--chip f446re|f411ce] [--pty] [--realtime] [--seconds S] \
     [--press AT_S] [--stall AT_S:MS] [--fault hardfault@AT_S|busfault@AT_S] \
     [--bridge pwm-dir|two-pwm|pwm-in1-in2] [--peak-from S] [--robot FILE] \
     [--flash-timing typ|max] [--flash-aged | --flash-robot FILE [--flash-pwm-hz N]] \
     [--usb-dtr-low AT_S:S] [--usb-stop-reading AT_S:S] [--usb-unplug AT_S:MS] \
     [--usb-corrupt device|config:OFFSET=VALUE] \
     [--imu-nack AT_S:N] [--imu-stuck-sda AT_S:CLOCKS] [--imu-asleep AT_S] \
     [--imu-frozen AT_S:MS] [--imu-implausible AT_S:MS[:RADPS]] [--imu-absent AT_S:MS] \
     [--summary FILE] [--quiet]"
        .into()
}

fn num(s: &str, what: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("{what}: `{s}` is not a number"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(format!("{what}: {v} must be finite and >= 0"));
    }
    Ok(v)
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        elf: String::new(),
        chip: ChipKind::F446re,
        pty: false,
        realtime: false,
        seconds: None,
        press: None,
        stall: None,
        fault: None,
        summary: None,
        quiet: false,
        bridge: None,
        peak_from: 0.0,
        robot: None,
        flash_timing: stm32_emu::periph::flash::FlashTiming::TYPICAL,
        flash_aged: false,
        flash_robot: None,
        flash_pwm_hz: None,
        usb_dtr_low: None,
        usb_stop_reading: None,
        usb_unplug: None,
        usb_corrupt: None,
        imu: Default::default(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut val = || {
            it.next()
                .ok_or_else(|| format!("{k} needs a value\n{}", usage()))
        };
        match k.as_str() {
            "--elf" => a.elf = val()?,
            "--chip" => {
                a.chip = match val()?.as_str() {
                    "f446re" => ChipKind::F446re,
                    "f411ce" => ChipKind::F411ce,
                    c => return Err(format!("--chip {c}: expected f446re or f411ce")),
                }
            }
            "--pty" => a.pty = true,
            "--realtime" => a.realtime = true,
            "--quiet" => a.quiet = true,
            "--seconds" => a.seconds = Some(num(&val()?, "--seconds")?),
            "--press" => a.press = Some(num(&val()?, "--press")?),
            "--stall" => {
                let v = val()?;
                let (t, ms) = v.split_once(':').ok_or("--stall AT_S:MS")?;
                let ms = num(ms, "--stall duration")?;
                if ms == 0.0 || ms > 10_000.0 {
                    return Err(format!("--stall {ms} ms: expected 0 < ms <= 10000"));
                }
                a.stall = Some((num(t, "--stall time")?, ms));
            }
            "--fault" => {
                let v = val()?;
                let (k, t) = v.split_once('@').ok_or("--fault KIND@AT_S")?;
                let f = match k {
                    "hardfault" => Fault::HardFault,
                    "busfault" => Fault::BusFaultOnEncoderRead,
                    _ => return Err(format!("--fault {k}: expected hardfault or busfault")),
                };
                a.fault = Some((f, num(t, "--fault time")?));
            }
            "--summary" => a.summary = Some(val()?),
            "--robot" => {
                let f = val()?;
                let text = std::fs::read_to_string(&f).map_err(|e| format!("--robot {f}: {e}"))?;
                a.robot = Some(
                    robot_file::Robot::from_toml_str(&text)
                        .map_err(|e| format!("--robot {f}: {e}"))?,
                );
            }
            "--flash-aged" => a.flash_aged = true,
            "--flash-robot" => {
                let f = val()?;
                let text =
                    std::fs::read_to_string(&f).map_err(|e| format!("--flash-robot {f}: {e}"))?;
                let r = robot_file::Robot::from_toml_str(&text)
                    .map_err(|e| format!("--flash-robot {f}: {e}"))?;
                a.flash_robot = Some((f, r));
            }
            "--flash-pwm-hz" => {
                let v = val()?;
                a.flash_pwm_hz = Some(
                    v.parse()
                        .map_err(|_| format!("--flash-pwm-hz {v}: not a whole number of Hz"))?,
                );
            }
            "--flash-timing" => {
                use stm32_emu::periph::flash::FlashTiming;
                a.flash_timing = match val()?.as_str() {
                    "typ" => FlashTiming::TYPICAL,
                    "max" => FlashTiming::MAX,
                    t => return Err(format!("--flash-timing {t}: expected typ or max")),
                }
            }
            "--bridge" => {
                use stm32_emu::bridge::BridgeMode as B;
                a.bridge = Some(match val()?.as_str() {
                    "pwm-dir" => B::PwmDir,
                    "two-pwm" => B::TwoPwm,
                    "pwm-in1-in2" => B::PwmIn1In2,
                    b => {
                        return Err(format!(
                            "--bridge {b}: expected pwm-dir, two-pwm or pwm-in1-in2"
                        ))
                    }
                })
            }
            "--peak-from" => a.peak_from = num(&val()?, "--peak-from")?,
            "--usb-dtr-low" => a.usb_dtr_low = Some(pair(&val()?, "--usb-dtr-low")?),
            "--usb-stop-reading" => a.usb_stop_reading = Some(pair(&val()?, "--usb-stop-reading")?),
            "--usb-unplug" => a.usb_unplug = Some(pair(&val()?, "--usb-unplug")?),
            "--usb-corrupt" => {
                let v = val()?;
                let bad =
                    || format!("--usb-corrupt {v}: expected device|config:OFFSET=VALUE (bytes)");
                let (which, rest) = v.split_once(':').ok_or_else(bad)?;
                let (o, x) = rest.split_once('=').ok_or_else(bad)?;
                let device = match which {
                    "device" => true,
                    "config" => false,
                    _ => return Err(bad()),
                };
                let offset: usize = o.parse().map_err(|_| bad())?;
                let value: u8 = x.parse().map_err(|_| bad())?;
                a.usb_corrupt = Some(stm32_emu::usb_host::Corrupt {
                    device,
                    offset,
                    value,
                });
            }
            "--imu-nack" => {
                let (t, n) = pair(&val()?, "--imu-nack")?;
                a.imu.nack = Some((ps(t), n as u32));
            }
            "--imu-stuck-sda" => {
                let (t, n) = pair(&val()?, "--imu-stuck-sda")?;
                if n > 9.0 {
                    return Err(format!(
                        "--imu-stuck-sda clocks {n}: at most 9 (a byte and its acknowledge)"
                    ));
                }
                a.imu.stuck_sda = Some((ps(t), n as u8));
            }
            "--imu-asleep" => a.imu.asleep = Some(ps(num(&val()?, "--imu-asleep")?)),
            "--imu-frozen" => {
                let (t, ms) = pair(&val()?, "--imu-frozen")?;
                a.imu.frozen = Some((ps(t), ps(ms * 1e-3)));
            }
            "--imu-implausible" => {
                // AT_S:MS or AT_S:MS:RADPS.
                let v = val()?;
                let (tm, rate) = match v.rsplit_once(':') {
                    Some((tm, r)) if tm.contains(':') => {
                        let r: f64 = r.parse().map_err(|_| {
                            format!("--imu-implausible {v}: RADPS `{r}` is not a number")
                        })?;
                        if !r.is_finite() {
                            return Err(format!("--imu-implausible {v}: RADPS must be finite"));
                        }
                        (tm.to_string(), Some(r))
                    }
                    _ => (v.clone(), None),
                };
                let (t, ms) = pair(&tm, "--imu-implausible")?;
                a.imu.implausible = Some((ps(t), ps(ms * 1e-3)));
                a.imu.implausible_radps = rate;
            }
            "--imu-absent" => {
                let (t, ms) = pair(&val()?, "--imu-absent")?;
                a.imu.absent = Some((ps(t), ps(ms * 1e-3)));
            }
            "-h" | "--help" => return Err(usage()),
            _ => return Err(format!("unknown argument {k}\n{}", usage())),
        }
    }
    if a.flash_aged && a.flash_robot.is_some() {
        return Err("--flash-aged and --flash-robot both set the store: choose one".into());
    }
    if a.flash_pwm_hz.is_some() && a.flash_robot.is_none() {
        return Err("--flash-pwm-hz changes the --flash-robot record: give --flash-robot".into());
    }
    if (a.usb_dtr_low.is_some()
        || a.usb_stop_reading.is_some()
        || a.usb_unplug.is_some()
        || a.usb_corrupt.is_some())
        && a.chip != ChipKind::F411ce
    {
        return Err("--usb-* need --chip f411ce (the F446 image's link is USART2)".into());
    }
    if a.elf.is_empty() {
        return Err(format!("--elf is required\n{}", usage()));
    }
    if !a.pty && a.seconds.is_none() {
        return Err("without --pty, --seconds is required (the run must end)".into());
    }
    Ok(a)
}

fn main() {
    match run() {
        Ok(code) => std::process::exit(code),
        Err(e) => {
            eprintln!("stm32-emu: {e}");
            std::process::exit(2);
        }
    }
}

const PS: f64 = 1e12;

fn run() -> Result<i32, String> {
    let a = parse_args()?;
    let bytes = std::fs::read(&a.elf).map_err(|e| format!("{}: {e}", a.elf))?;
    let image = stm32_emu::elf::Image::parse(&bytes).map_err(|e| format!("{}: {e}", a.elf))?;
    let mut m = Machine::new(a.chip, image)?;
    m.board().verbose = !a.quiet;
    // The harness's bridges are wired as --bridge says, else as the
    // robot file's [bridge], else PWM + DIR.
    m.board().bridge_mode = a
        .bridge
        .or(a.robot.as_ref().map(|r| r.bridge.params().mode))
        .unwrap_or(stm32_emu::bridge::BridgeMode::PwmDir);
    if let Some(r) = &a.robot {
        m.board().robot = stm32_emu::robot::Robot::of_file(r)?;
    }
    // The MPU-6050 mounted as the robot file's imu.yaw_axis says (the
    // compiled-in paper robot's is +z).
    let (axis, sign) = a
        .robot
        .as_ref()
        .map_or((2, 1.0), |r| r.imu.yaw_axis.axis_and_sign());
    m.board().mpu = stm32_emu::mpu6050::Mpu6050::new(axis, sign < 0.0);
    m.board().mpu.faults = a.imu;
    // The firmware's gyro cell (firmware::imu::LATEST, `imu` images):
    // what the board's gyro hands the estimator every tick.
    let gyro_cell = m.symbol_prefix("_ZN8firmware3imu6LATEST17h");
    let mut gyro = GyroWatch::default();
    m.board().flash().timing = a.flash_timing;
    m.board().peak_from_s = a.peak_from;
    if let Some(h) = m.board().usb_host.as_mut() {
        h.corrupt = a.usb_corrupt;
    }
    if !a.quiet {
        for e in &m.board().events {
            eprintln!("[stm32-emu t={:10.6} s] {}", e.t_s, e.what);
        }
    }

    if a.flash_aged {
        let robot = a.robot.clone().unwrap_or_else(robot_file::Robot::paper);
        let mut blob = [0u8; robot_file::MAX_ENCODED_LEN];
        let n = robot
            .encode(&mut blob)
            .map_err(|e| format!("--flash-aged: {e:?}"))?;
        let (bytes, saves) = stm32_emu::periph::flash::aged_store(&blob[..n])?;
        m.board().flash().store = bytes;
        m.board().event(format!(
            "flash: store aged by {saves} saves of \"{}\" (the next save erases a sector)",
            robot.name
        ));
    }

    if let Some((f, robot)) = &a.flash_robot {
        let mut robot = robot.clone();
        // A crafted record: the field replaced after robot-file's
        // validation, encoded with a valid CRC, saved without a check.
        let validate: robot_store::RobotValidator = match a.flash_pwm_hz {
            Some(hz) => {
                robot.bridge.pwm_frequency_hz = hz;
                |_| Ok(())
            }
            None => robot_store::validate_robot,
        };
        let mut blob = [0u8; robot_file::MAX_ENCODED_LEN];
        let n = robot
            .encode(&mut blob)
            .map_err(|e| format!("--flash-robot {f}: {e:?}"))?;
        m.board().flash().store = stm32_emu::periph::flash::stored_store(&blob[..n], validate)?;
        m.board().event(format!(
            "flash: the store holds \"{}\" ({f}, {n} B, saved once{})",
            robot.name,
            a.flash_pwm_hz.map_or(String::new(), |hz| format!(
                ", crafted: bridge.pwm_frequency_hz = {hz}, not validated"
            ))
        ));
    }

    // The host link: a pty pair, the slave kept open (hosts come and go).
    let mut link = if a.pty {
        use serialport::SerialPort;
        let (mut master, slave) = serialport::TTYPort::pair()
            .map_err(|e| format!("cannot open a pseudo-terminal: {e}"))?;
        master
            .set_timeout(Duration::ZERO)
            .map_err(|e| format!("pty: {e}"))?;
        let path = slave.name().ok_or("pty: the slave side has no path")?;
        println!("{path}");
        let _ = std::io::stdout().flush();
        Some((master, slave))
    } else {
        None
    };

    let wall0 = Instant::now();
    // Wall time [s] the emulation fell behind and gave up catching up.
    let mut lag_dropped_s = 0.0f64;
    let until = a.seconds.map_or(u128::MAX, |s| (s * PS) as u128);
    let mut pressed = false;
    let mut released = false;
    let mut stalled = false;
    let mut faulted: Option<u128> = None;
    let mut usb_unplugged = false;
    let mut cut_after_fault: Option<f64> = None;
    let mut tx_pending: Vec<u8> = Vec::new();
    let mut buf = [0u8; 512];
    let poll_ps = 1_000_000_000; // 1 ms
    let trace = std::env::var_os("STM32_EMU_TRACE_LINK").is_some();
    let mut next_alive = 1.0;
    let mut poll = |m: &mut Machine| -> Result<(), String> {
        let now = m.board().now_ps();
        // Host link.
        if let Some((master, _)) = link.as_mut() {
            loop {
                if !m.board().link_has_room() {
                    break; // the writer blocks, as on a busy /dev/ttyACM0
                }
                match master.read(&mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        if trace {
                            let t = now as f64 / PS;
                            eprintln!("[link t={t:10.6}] host -> {n} B");
                        }
                        m.board().link_from_host(&buf[..n])
                    }
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::WouldBlock
                                | std::io::ErrorKind::TimedOut
                                | std::io::ErrorKind::Interrupted
                        ) =>
                    {
                        break
                    }
                    Err(_) => break, // no host: EIO while the slave is closed
                }
            }
            let mut out = m.board().link_to_host();
            if trace && !out.is_empty() {
                let t = now as f64 / PS;
                eprintln!("[link t={t:10.6}] device -> {} B", out.len());
            }
            tx_pending.append(&mut out);
            if !tx_pending.is_empty() {
                // A full pty (EAGAIN) or no host (EIO): keep the bytes for later.
                if let Ok(n) = master.write(&tx_pending) {
                    tx_pending.drain(..n);
                }
                // Nobody reading: a real UART's bytes are lost on the wire.
                if tx_pending.len() > 64 * 1024 {
                    tx_pending.clear();
                }
            }
        } else {
            m.board().link_to_host();
        }
        // Script.
        let t_s = now as f64 / PS;
        if !a.quiet && t_s >= next_alive {
            // A line per emulated second: scripts read the emulated time.
            next_alive += 1.0;
            let stack = m.stack_usage().map_or(String::new(), |u| {
                format!(
                    " (stack high-water {} B running, {} B at boot, of {} B)",
                    u.used_bytes, u.boot_bytes, u.size_bytes
                )
            });
            let d = m.uc.get_data();
            let usb = d.usb_host.as_ref().map_or(String::new(), |h| {
                let u = &d.usb.stats;
                format!(
                    " (usb: configured {}x, IN {} B, OUT {} B, IN NAKs {}, out NAKs {}, lost {} B)",
                    h.configured, h.in_bytes, h.out_bytes, u.in_naks, u.out_naks, h.lost_bytes
                )
            });
            let t = m.uc.get_data().step_probe.calls;
            let ticks = if t.n > 0 {
                format!(
                    " (control step {} instructions mean, {} max, {} calls)",
                    t.mean(),
                    t.max,
                    t.n
                )
            } else {
                String::new()
            };
            m.board().event(format!("alive{stack}{ticks}{usb}"));
        }
        if let Some(at) = a.press {
            if !pressed && t_s >= at {
                pressed = true;
                let (port, pin, name) = a.chip.button();
                m.board().gpio[port].drive(pin, Some(false));
                m.board().event(format!("arm button {name} pressed"));
            }
            if pressed && !released && t_s >= at + 0.1 {
                released = true;
                let (port, pin, name) = a.chip.button();
                m.board().gpio[port].drive(pin, None);
                m.board().event(format!("arm button {name} released"));
            }
        }
        if let Some((at, ms)) = a.stall {
            if !stalled && t_s >= at {
                stalled = true;
                m.stall((ms * 1e9) as u128);
            }
        }
        if let Some(h) = m.board().usb_host.as_mut() {
            let (mut ev, now_ps) = (Vec::new(), now);
            if let Some((at, s)) = a.usb_dtr_low {
                let low = t_s >= at && t_s < at + s;
                if h.dtr == low {
                    h.dtr = !low;
                    ev.push(format!(
                        "USB host: DTR {} requested (--usb-dtr-low); {} B received so far",
                        if low { "low" } else { "high" },
                        h.in_bytes
                    ));
                }
            }
            if let Some((at, s)) = a.usb_stop_reading {
                let stop = t_s >= at && t_s < at + s;
                if h.reading == stop {
                    h.reading = !stop;
                    ev.push(format!(
                        "USB host: {} reading bulk IN (--usb-stop-reading); {} B received so far",
                        if stop { "stops" } else { "resumes" },
                        h.in_bytes
                    ));
                }
            }
            if let Some((at, ms)) = a.usb_unplug {
                if !usb_unplugged && t_s >= at {
                    usb_unplugged = true;
                    h.unplug(now_ps, (ms * 1e9) as u128);
                }
            }
            for e in ev {
                m.board().event(e);
            }
        }
        if let Some(addr) = gyro_cell {
            gyro.poll(m, addr, t_s)?;
        }
        if let Some((f, at)) = a.fault {
            if faulted.is_none() && t_s >= at {
                faulted = Some(now);
                m.inject(f);
            }
        }
        // Pacing: emulated time never ahead of the wall clock, and never
        // more than 0.1 s behind it: a fall-behind (a loaded machine) is
        // dropped, not caught up at full speed (~3x real time), which would
        // stretch the host's wall-clock keep-alives in emulated time towards
        // the robot's link timeout (as hil-sim's device does).
        if a.realtime {
            let wall = wall0.elapsed().as_secs_f64() - lag_dropped_s;
            if t_s > wall + 0.002 {
                std::thread::sleep(Duration::from_secs_f64(t_s - wall));
            } else if wall - t_s > 0.1 {
                lag_dropped_s += wall - t_s;
            }
        }
        Ok(())
    };
    // The fault check needs finer resolution than the 1 ms poll: run in
    // slices and look at the outputs after each.
    let mut result: Result<(), String> = Ok(());
    let mut t_next = 0u128;
    let slice = 100_000_000u128; // 100 µs
    while t_next < until {
        t_next = (t_next + slice).min(until);
        if let Err(e) = m.run_until(t_next, poll_ps, &mut poll) {
            result = Err(e);
            break;
        }
        let d = m.board();
        if let (Some(f), None) = (faulted_time(&d.events), cut_after_fault) {
            if let Ok(b) = d.bridge() {
                if b.all_low() {
                    cut_after_fault = Some(d.now_s() - f);
                }
            }
        }
    }
    let _ = faulted;
    let wall = wall0.elapsed().as_secs_f64();
    let stack = m.stack_usage();
    let d = m.board();
    let emu_s = d.now_s();
    let bridge = d.bridge().ok();
    let iwdg_resets = d
        .stats
        .resets
        .iter()
        .filter(|r| r.1 == stm32_emu::periph::rcc::ResetCause::Iwdg)
        .count();
    let taken = |e: usize| d.stats.taken.get(&e).copied().unwrap_or(0);
    let pose = d.robot.pose();
    let mut s = String::new();
    s += "{";
    s += &format!("\"ok\":{},", result.is_ok());
    s += &format!(
        "\"error\":\"{}\",",
        result
            .as_ref()
            .err()
            .map_or(String::new(), |e| e.replace('"', "'"))
    );
    s += &format!(
        "\"emulated_s\":{emu_s:.6},\"wall_s\":{wall:.3},\"speed_x\":{:.2},",
        emu_s / wall.max(1e-9)
    );
    s += &format!(
        "\"instructions\":{},\"slices\":{},\"sleeps\":{},",
        d.stats.instructions, d.stats.slices, d.stats.sleeps
    );
    s += &format!("\"boots\":{},\"iwdg_resets\":{iwdg_resets},", d.stats.boots);
    s += &format!(
        "\"taken_in_it_block\":{},\"min_sp\":\"0x{:08X}\",",
        d.stats.taken_in_it_block, d.stats.min_sp
    );
    if let Some(u) = stack {
        s += &format!(
            "\"stack_used_bytes\":{},\"stack_boot_bytes\":{},\"stack_size_bytes\":{},",
            u.used_bytes, u.boot_bytes, u.size_bytes
        );
    }
    s += &format!(
        "\"csr_at_boot\":\"0x{:08X}\",\"iwdgrstf\":{},",
        d.csr_at_boot,
        d.csr_at_boot & csr::IWDGRSTF != 0
    );
    s += &format!(
        "\"idle_reached\":{},\"loop_started\":{},",
        d.idle_reached, d.loop_started
    );
    s += &format!(
        "\"feeds\":{},\"tim5_irqs\":{},\"usart2_irqs\":{},\"hardfaults\":{},",
        d.stats.feeds,
        taken(16 + 50),
        taken(16 + 38),
        taken(3)
    );
    s += &format!(
        "\"usart2_rx_bytes\":{},\"usart2_tx_bytes\":{},\"usart2_overruns\":{},",
        d.usart2.rx_bytes, d.usart2.tx_bytes, d.usart2.overruns
    );
    if let Some(b) = bridge {
        s += &format!(
            "\"motors_off\":{},\"motor_pins_low\":{},\"enable\":{},\"pwm\":[{},{}],",
            b.motors_off(),
            b.all_low(),
            b.enable,
            b.pwm[0].0,
            b.pwm[1].0
        );
    }
    if let Some(c) = cut_after_fault {
        s += &format!("\"motors_cut_after_fault_poll_us\":{:.1},", c * 1e6);
    }
    if let Some((ps, n)) = d.cut_after_fault {
        s += &format!(
            "\"motors_cut_after_fault_us\":{:.3},\"motors_cut_after_fault_insn\":{n},",
            ps as f64 * 1e-6
        );
    }
    if let Some(h) = &d.usb_host {
        let u = &d.usb.stats;
        s += &format!(
            "\"usb_configured\":{},\"usb_lost_bytes\":{},\"usb_in_bytes\":{},\"usb_out_bytes\":{},\"usb_in_naks\":{},\"usb_out_naks\":{},\"usb_setups\":{},\"usb_bus_resets\":{},\"usb_frames\":{},\"otg_irqs\":{},",
            h.configured, h.lost_bytes, h.in_bytes, h.out_bytes, u.in_naks, u.out_naks, u.setups, u.bus_resets, h.frames, taken(16 + 67)
        );
    }
    s += &format!(
        "\"step_insn_mean\":{},\"step_insn_max\":{},\"step_calls\":{},",
        d.step_probe.calls.mean(),
        d.step_probe.calls.max,
        d.step_probe.calls.n
    );
    s += &format!("\"pose\":[{:.4},{:.4},{:.4}],", pose[0], pose[1], pose[2]);
    s += &format!(
        "\"armature_peak\":[{:.4},{:.4}],\"bridge_transients\":{},",
        d.armature_peak[0].0, d.armature_peak[1].0, d.bridge_transients
    );
    if gyro_cell.is_some() {
        let i = &d.i2c1.stats;
        let c = &d.mpu.stats;
        s += &format!(
            "\"i2c_starts\":{},\"i2c_stops\":{},\"i2c_address_nacks\":{},\"i2c_bytes\":{},\"dma1_items\":{},",
            i.starts, i.stops, i.address_nacks, i.bytes, d.dma1.items
        );
        s += &format!(
            "\"mpu_acks\":{},\"mpu_nacks\":{},\"mpu_gyro_reads\":{},\"mpu_resets\":{},\"mpu_recovery_clocks\":{},\"mpu_regs\":\"{}\",",
            c.acks, c.nacks, c.gyro_reads, c.resets, c.recovery_clocks, d.mpu.report()
        );
        s += &gyro.json();
    }
    s += &format!(
        "\"sysclk_hz\":{},\"plant_steps\":{}",
        d.sysclk_hz, d.robot.steps
    );
    s += "}";
    match &a.summary {
        Some(f) => std::fs::write(f, format!("{s}\n")).map_err(|e| format!("{f}: {e}"))?,
        None => println!("{s}"),
    }
    match result {
        Ok(()) => Ok(0),
        Err(e) => {
            eprintln!("stm32-emu: run failed at t = {emu_s:.6} s: {e}");
            eprintln!("{}", m.board().trace_dump());
            Ok(1)
        }
    }
}

fn faulted_time(events: &[stm32_emu::machine::Event]) -> Option<f64> {
    events
        .iter()
        .find(|e| e.what.starts_with("fault injected"))
        .map(|e| e.t_s)
}

/// The firmware's gyro cell watched every poll (1 ms): `Option<GyroSample>`
/// as rustc lays it out for the thumbv7em target (a u32 tag, then
/// `rate_radps: f32`, `stamp_us: u32`); a tag other than 0/1 fails the run
/// (a layout this watch does not know).
#[derive(Default)]
struct GyroWatch {
    polls: u64,
    valid: u64,
    first_valid_s: Option<f64>,
    /// Spans [from, to) with the cell empty after the first sample (`to`
    /// open while empty).
    empty: Vec<(f64, Option<f64>)>,
    last_stamp: Option<u32>,
    fresh: u64,
    err_sum: f64,
    max_abs: f64,
}

impl GyroWatch {
    fn poll(&mut self, m: &mut Machine, addr: u32, t_s: f64) -> Result<(), String> {
        let mut b = [0u8; 12];
        if m.uc.mem_read(addr as u64, &mut b).is_err() {
            return Ok(());
        }
        let w = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let tag = w(0);
        if tag > 1 {
            return Err(format!(
                "gyro cell at 0x{addr:08X}: tag {tag}: not the Option<GyroSample> layout this harness reads"
            ));
        }
        self.polls += 1;
        let valid = tag == 1;
        if valid {
            self.valid += 1;
            let rate = f32::from_bits(w(4)) as f64;
            let stamp = w(8);
            self.max_abs = self.max_abs.max(rate.abs());
            if self.first_valid_s.is_none() {
                self.first_valid_s = Some(t_s);
                m.board()
                    .event(format!("gyro cell: first sample ({rate:+.4} rad/s)"));
            }
            if let Some((_, to @ None)) = self.empty.last_mut() {
                *to = Some(t_s);
                m.board().event(format!(
                    "gyro cell: sample again ({rate:+.4} rad/s): the estimator has the gyro"
                ));
            }
            if self.last_stamp != Some(stamp) {
                self.last_stamp = Some(stamp);
                self.fresh += 1;
                let truth = m.board().robot.yaw_rate_radps();
                self.err_sum += (rate - truth).abs();
            }
        } else if self.first_valid_s.is_some() && !matches!(self.empty.last(), Some((_, None))) {
            self.empty.push((t_s, None));
            m.board()
                .event("gyro cell: empty: the estimator uses the wheels".into());
        }
        Ok(())
    }

    fn json(&self) -> String {
        let spans: Vec<String> = self
            .empty
            .iter()
            .map(|(a, b)| {
                format!(
                    "[{a:.4},{}]",
                    b.map_or("null".into(), |b| format!("{b:.4}"))
                )
            })
            .collect();
        format!(
            "\"gyro_polls\":{},\"gyro_valid_polls\":{},\"gyro_first_valid_s\":{},\"gyro_empty_spans\":[{}],\"gyro_fresh_samples\":{},\"gyro_err_mean_radps\":{:.6},\"gyro_max_abs_radps\":{:.4},",
            self.polls,
            self.valid,
            self.first_valid_s.map_or("null".into(), |t| format!("{t:.4}")),
            spans.join(","),
            self.fresh,
            self.err_sum / self.fresh.max(1) as f64,
            self.max_abs
        )
    }
}
