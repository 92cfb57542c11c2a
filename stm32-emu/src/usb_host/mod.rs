//! A USB host written from the USB 2.0 specification (chapters 7-9) and
//! CDC 1.2 / PSTN 1.2, not from embassy-usb: it attaches to the OTG_FS
//! device model ([`crate::periph::otg_fs`]), debounces the connect (100
//! ms, §7.1.7.3), resets the bus (10 ms, §7.1.7.5) with a 10 ms recovery,
//! reads the device descriptor, sets the address (2 ms recovery,
//! §9.2.6.3), reads the device, configuration and string descriptors and
//! checks each ([`descriptors`]), sets the configuration, sets and reads
//! back the line coding, sets DTR/RTS (SET_CONTROL_LINE_STATE), then moves
//! the CDC data: bulk OUT from [`UsbHost::send`] (the pty's bytes),
//! bulk IN into [`UsbHost::in_data`], the notification endpoint polled at
//! its bInterval.
//!
//! Schedule: a transaction slot every [`SLOT_PS`] (100 µs) and a frame
//! (SOF) every ten: each slot the host tries at most one transaction per
//! pipe (the control pipe first), so the device's CPU runs between the
//! stages of a control transfer and between bulk packets (up to 640 B/ms
//! each way). Timeouts from §9.2.6.4: a request with a data stage must
//! return its first packet within 500 ms and complete within 5 s, one
//! without within 50 ms; three transactions without an answer fail a
//! transfer (§8.5: the host's error count). Any failure ends the run with
//! the request and the reason.

pub mod descriptors;

use crate::periph::otg_fs::{Handshake, OtgFs};
use descriptors::{Config, DescError, DeviceDesc};
use std::collections::VecDeque;

/// One transaction slot \[ps\] (100 µs).
pub const SLOT_PS: u128 = 100_000_000;
/// Slots per frame (1 ms).
pub const SLOTS_PER_FRAME: u64 = 10;
const MS: u128 = 1_000_000_000;
/// The address the host assigns.
pub const ADDRESS: u8 = 1;
/// The line coding the host sets: 115 200 baud, 1 stop bit, no parity,
/// 8 data bits (PSTN 1.2 Table 17).
pub const LINE_CODING: [u8; 7] = [0x00, 0xC2, 0x01, 0x00, 0, 0, 8];
/// Bytes received and not yet taken (by the pty) above which the host
/// stops polling bulk IN (as Linux's tty throttles cdc-acm's reads).
pub const IN_THROTTLE_BYTES: usize = 4096;

/// Why the host gave up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HostError {
    /// A descriptor breaks the specification.
    Descriptor {
        /// The request that returned it.
        request: &'static str,
        /// What is wrong.
        error: DescError,
    },
    /// The device STALLed a request the function must support.
    Stall {
        /// The request.
        request: &'static str,
    },
    /// Three transactions without an answer.
    NoAnswer {
        /// The request or pipe.
        request: &'static str,
    },
    /// Not completed within the specification's limit.
    TimedOut {
        /// The request.
        request: &'static str,
        /// The limit \[ms\].
        limit_ms: u64,
    },
    /// Another protocol violation.
    Protocol {
        /// The request or pipe.
        request: &'static str,
        /// What happened.
        what: String,
    },
}

impl core::fmt::Display for HostError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Descriptor { request, error } => write!(f, "USB host: {request}: {error}"),
            Self::Stall { request } => write!(f, "USB host: {request}: STALL"),
            Self::NoAnswer { request } => {
                write!(f, "USB host: {request}: no answer to three transactions")
            }
            Self::TimedOut { request, limit_ms } => write!(
                f,
                "USB host: {request}: not completed within {limit_ms} ms (USB 2.0 §9.2.6.4)"
            ),
            Self::Protocol { request, what } => write!(f, "USB host: {request}: {what}"),
        }
    }
}

impl std::error::Error for HostError {}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Setup,
    DataIn,
    DataOut,
    StatusIn,
    StatusOut,
}

#[derive(Clone, Debug)]
struct Ctrl {
    what: &'static str,
    setup: [u8; 8],
    out: Vec<u8>,
    sent: usize,
    got: Vec<u8>,
    stage: Stage,
    errors: u32,
    started_ps: u128,
    first_data_ps: Option<u128>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    DevHead,
    SetAddress,
    Device,
    ConfigHead,
    Config,
    Langids,
    Strings(usize),
    SetConfiguration,
    SetLineCoding,
    GetLineCoding,
    SetControlLineState,
}

#[derive(Clone, Debug, PartialEq, Eq)]
enum Phase {
    /// No pull-up seen, or unplugged until the time given.
    Detached {
        until_ps: Option<u128>,
        idle_since_ps: u128,
    },
    Debounce {
        until_ps: u128,
    },
    Reset {
        until_ps: u128,
    },
    Recovery {
        until_ps: u128,
    },
    Enumerating,
    Running,
}

/// What the host learnt at enumeration.
#[derive(Clone, Debug)]
pub struct Enumerated {
    /// The device descriptor.
    pub device: DeviceDesc,
    /// The configuration.
    pub config: Config,
    /// Manufacturer, product, serial number strings (empty when absent).
    pub strings: [String; 3],
}

/// The host.
#[derive(Clone, Debug)]
pub struct UsbHost {
    phase: Phase,
    step: Step,
    ctrl: Option<Ctrl>,
    wait_until_ps: u128,
    slot: u64,
    next_ps: u128,
    mps0: usize,
    addr: u8,
    total_len: u16,
    langid: u16,
    device: Option<DeviceDesc>,
    config: Option<Config>,
    strings: [String; 3],
    /// The enumerated device (once configured).
    pub enumerated: Option<Enumerated>,
    /// Bytes for the bulk OUT endpoint (from the pty).
    out_queue: VecDeque<u8>,
    /// Bytes the host program wrote while the device was not configured
    /// (unplugged, enumerating): lost, as writes to a vanished
    /// /dev/ttyACM0 are.
    pub lost_bytes: u64,
    out_packet: Option<Vec<u8>>,
    out_errors: u32,
    /// Bytes from the bulk IN endpoint, not yet taken.
    pub in_data: Vec<u8>,
    /// The DTR the host wants (a program has the port open).
    pub dtr: bool,
    dtr_sent: Option<bool>,
    /// The host polls bulk IN (false: it stopped reading).
    pub reading: bool,
    /// Unplugged (no SOF, no traffic) until this time \[ps\].
    unplug_until_ps: Option<u128>,
    /// Events for the log.
    pub events: Vec<String>,
    /// Bytes received on bulk IN, in total.
    pub in_bytes: u64,
    /// Bytes sent on bulk OUT, in total.
    pub out_bytes: u64,
    /// Times the device was configured.
    pub configured: u64,
    /// Frames (SOF) sent.
    pub frames: u64,
    /// Fault injection (a negative control): the byte at this offset of
    /// the descriptor received is replaced before the checks.
    pub corrupt: Option<Corrupt>,
}

/// A descriptor byte the host replaces on receipt (`--usb-corrupt`): the
/// checks must then fail naming the field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Corrupt {
    /// In the device descriptor (else the whole configuration).
    pub device: bool,
    /// Byte offset.
    pub offset: usize,
    /// The value put there.
    pub value: u8,
}

impl Default for UsbHost {
    fn default() -> Self {
        Self::new()
    }
}

fn setup_packet(bm: u8, req: u8, value: u16, index: u16, length: u16) -> [u8; 8] {
    let mut s = [bm, req, 0, 0, 0, 0, 0, 0];
    s[2..4].copy_from_slice(&value.to_le_bytes());
    s[4..6].copy_from_slice(&index.to_le_bytes());
    s[6..8].copy_from_slice(&length.to_le_bytes());
    s
}

impl UsbHost {
    /// A host with DTR raised (a program has the port open) and reading.
    pub fn new() -> Self {
        Self {
            phase: Phase::Detached {
                until_ps: None,
                idle_since_ps: 0,
            },
            step: Step::DevHead,
            ctrl: None,
            wait_until_ps: 0,
            slot: 0,
            next_ps: SLOT_PS,
            mps0: 64,
            addr: 0,
            total_len: 0,
            langid: 0,
            device: None,
            config: None,
            strings: Default::default(),
            enumerated: None,
            out_queue: VecDeque::new(),
            lost_bytes: 0,
            out_packet: None,
            out_errors: 0,
            in_data: Vec::new(),
            dtr: true,
            dtr_sent: None,
            reading: true,
            unplug_until_ps: None,
            events: Vec::new(),
            in_bytes: 0,
            out_bytes: 0,
            configured: 0,
            frames: 0,
            corrupt: None,
        }
    }

    /// The next slot \[ps\].
    pub fn next_event_ps(&self) -> u128 {
        self.next_ps
    }

    /// Bytes from the host program for the bulk OUT endpoint; lost while
    /// the device is not configured.
    pub fn send(&mut self, bytes: &[u8]) {
        if self.phase == Phase::Running {
            self.out_queue.extend(bytes);
        } else {
            self.lost_bytes += bytes.len() as u64;
        }
    }

    /// Bytes queued for bulk OUT.
    pub fn out_pending(&self) -> usize {
        self.out_queue.len() + self.out_packet.as_ref().map_or(0, |p| p.len())
    }

    /// The device is configured and its data pipes run.
    pub fn running(&self) -> bool {
        self.phase == Phase::Running
    }

    /// Unplugs the cable now for `ps`; on re-plug the host debounces,
    /// resets and enumerates again.
    pub fn unplug(&mut self, now_ps: u128, ps: u128) {
        self.unplug_until_ps = Some(now_ps + ps);
        self.phase = Phase::Detached {
            until_ps: Some(now_ps + ps),
            idle_since_ps: now_ps,
        };
        self.ctrl = None;
        self.out_packet = None;
        self.out_queue.clear();
        self.dtr_sent = None;
        self.events.push(format!(
            "USB host: cable unplugged for {:.1} ms",
            ps as f64 / MS as f64
        ));
    }

    fn start(&mut self, what: &'static str, setup: [u8; 8], out: Vec<u8>, now_ps: u128) {
        self.ctrl = Some(Ctrl {
            what,
            setup,
            out,
            sent: 0,
            got: Vec::new(),
            stage: Stage::Setup,
            errors: 0,
            started_ps: now_ps,
            first_data_ps: None,
        });
    }

    fn get_descriptor(
        &mut self,
        what: &'static str,
        ty: u8,
        index: u8,
        langid: u16,
        len: u16,
        now: u128,
    ) {
        let s = setup_packet(0x80, 6, ((ty as u16) << 8) | index as u16, langid, len);
        self.start(what, s, Vec::new(), now);
    }

    fn issue(&mut self, now: u128) {
        let comm = self
            .config
            .as_ref()
            .map_or(0, |c| c.acm.comm_interface as u16);
        match self.step {
            Step::DevHead => {
                self.get_descriptor("GET_DESCRIPTOR(DEVICE, 64) at address 0", 1, 0, 0, 64, now)
            }
            Step::SetAddress => self.start(
                "SET_ADDRESS",
                setup_packet(0, 5, ADDRESS as u16, 0, 0),
                Vec::new(),
                now,
            ),
            Step::Device => self.get_descriptor("GET_DESCRIPTOR(DEVICE)", 1, 0, 0, 18, now),
            Step::ConfigHead => {
                self.get_descriptor("GET_DESCRIPTOR(CONFIGURATION, 9)", 2, 0, 0, 9, now)
            }
            Step::Config => {
                let n = self.total_len;
                self.get_descriptor("GET_DESCRIPTOR(CONFIGURATION)", 2, 0, 0, n, now)
            }
            Step::Langids => self.get_descriptor("GET_DESCRIPTOR(STRING 0)", 3, 0, 0, 255, now),
            Step::Strings(i) => {
                let idx = self.device.as_ref().map_or(0, |d| d.strings[i]);
                let l = self.langid;
                self.get_descriptor("GET_DESCRIPTOR(STRING)", 3, idx, l, 255, now)
            }
            Step::SetConfiguration => {
                let v = self.config.as_ref().map_or(1, |c| c.value) as u16;
                self.start(
                    "SET_CONFIGURATION",
                    setup_packet(0, 9, v, 0, 0),
                    Vec::new(),
                    now,
                )
            }
            Step::SetLineCoding => self.start(
                "SET_LINE_CODING",
                setup_packet(0x21, 0x20, 0, comm, 7),
                LINE_CODING.to_vec(),
                now,
            ),
            Step::GetLineCoding => self.start(
                "GET_LINE_CODING",
                setup_packet(0xA1, 0x21, 0, comm, 7),
                Vec::new(),
                now,
            ),
            Step::SetControlLineState => self.set_control_line_state(now),
        }
    }

    fn set_control_line_state(&mut self, now: u128) {
        let comm = self
            .config
            .as_ref()
            .map_or(0, |c| c.acm.comm_interface as u16);
        // wValue bit 0 DTR, bit 1 RTS (PSTN 1.2 Table 18).
        let v = if self.dtr { 3 } else { 0 };
        self.dtr_sent = Some(self.dtr);
        self.start(
            "SET_CONTROL_LINE_STATE",
            setup_packet(0x21, 0x22, v, comm, 0),
            Vec::new(),
            now,
        );
    }

    /// A control transfer ended with `data` (the data stage's bytes).
    fn done(&mut self, what: &'static str, mut data: Vec<u8>, now: u128) -> Result<(), HostError> {
        let de = |error| HostError::Descriptor {
            request: what,
            error,
        };
        if let Some(c) = self.corrupt {
            let hit = match self.step {
                Step::Device => c.device,
                Step::Config => !c.device,
                _ => false,
            };
            if hit && c.offset < data.len() {
                self.events.push(format!(
                    "USB host: fault injected: {} byte {} 0x{:02X} -> 0x{:02X}",
                    if c.device {
                        "device descriptor"
                    } else {
                        "configuration"
                    },
                    c.offset,
                    data[c.offset],
                    c.value
                ));
                data[c.offset] = c.value;
            }
        }
        let mut next = None;
        match self.step {
            Step::DevHead => {
                self.mps0 = descriptors::device_head(&data).map_err(de)? as usize;
                next = Some(Step::SetAddress);
            }
            Step::SetAddress => {
                self.addr = ADDRESS;
                self.wait_until_ps = now + 2 * MS;
                next = Some(Step::Device);
            }
            Step::Device => {
                let d = descriptors::device(&data).map_err(de)?;
                if d.max_packet_size0 as usize != self.mps0 {
                    return Err(de(DescError::Field {
                        desc: "device".into(),
                        field: "bMaxPacketSize0",
                        value: d.max_packet_size0 as u32,
                        expected: "the value read at address 0",
                    }));
                }
                self.device = Some(d);
                next = Some(Step::ConfigHead);
            }
            Step::ConfigHead => {
                self.total_len = descriptors::config_head(&data).map_err(de)?;
                next = Some(Step::Config);
            }
            Step::Config => {
                self.config = Some(descriptors::config(&data).map_err(de)?);
                next = Some(Step::Langids);
            }
            Step::Langids => {
                let l = descriptors::langids(&data).map_err(de)?;
                self.langid = l[0];
                next = Some(self.next_string(0));
            }
            Step::Strings(i) => {
                let idx = self.device.as_ref().map_or(0, |d| d.strings[i]);
                self.strings[i] = descriptors::string(idx, &data).map_err(de)?;
                next = Some(self.next_string(i + 1));
            }
            Step::SetConfiguration => next = Some(Step::SetLineCoding),
            Step::SetLineCoding => next = Some(Step::GetLineCoding),
            Step::GetLineCoding => {
                if data != LINE_CODING {
                    return Err(HostError::Protocol {
                        request: what,
                        what: format!("line coding {data:02X?} read back, {LINE_CODING:02X?} set"),
                    });
                }
                next = Some(Step::SetControlLineState);
            }
            Step::SetControlLineState => {
                if self.phase == Phase::Enumerating {
                    self.phase = Phase::Running;
                    self.configured += 1;
                    let (Some(device), Some(config)) = (self.device.clone(), self.config.clone())
                    else {
                        return Err(HostError::Protocol {
                            request: what,
                            what: "configured without descriptors".into(),
                        });
                    };
                    let a = &config.acm;
                    self.events.push(format!(
                        "USB host: configured ({:04X}:{:04X} \"{}\" \"{}\" serial \"{}\", bcdUSB {:X}, EP0 {} B, CDC {:X}, ACM caps 0x{:02X}, bulk IN 0x{:02X}/OUT 0x{:02X} {} B, notify 0x{:02X} every {} ms), DTR {}",
                        device.vid_pid.0,
                        device.vid_pid.1,
                        self.strings[0],
                        self.strings[1],
                        self.strings[2],
                        device.bcd_usb,
                        device.max_packet_size0,
                        a.bcd_cdc,
                        a.acm_capabilities,
                        a.bulk_in.address,
                        a.bulk_out.address,
                        a.bulk_in.max_packet_size,
                        a.notify.address,
                        a.notify.interval,
                        if self.dtr { "high" } else { "low" }
                    ));
                    self.enumerated = Some(Enumerated {
                        device,
                        config,
                        strings: self.strings.clone(),
                    });
                } else {
                    self.events.push(format!(
                        "USB host: DTR {} (SET_CONTROL_LINE_STATE done), {} B received so far",
                        if self.dtr_sent == Some(true) {
                            "high"
                        } else {
                            "low"
                        },
                        self.in_bytes
                    ));
                }
            }
        }
        if let Some(n) = next {
            self.step = n;
        }
        Ok(())
    }

    fn next_string(&self, from: usize) -> Step {
        let s = self.device.as_ref().map_or([0; 3], |d| d.strings);
        (from..3)
            .find(|&i| s[i] != 0)
            .map_or(Step::SetConfiguration, Step::Strings)
    }

    /// Runs the slots up to `now_ps`.
    pub fn sync(&mut self, dev: &mut OtgFs, now_ps: u128) -> Result<(), HostError> {
        while self.next_ps <= now_ps {
            let t = self.next_ps;
            self.slot_at(dev, t)?;
            self.slot += 1;
            self.next_ps += SLOT_PS;
        }
        Ok(())
    }

    fn slot_at(&mut self, dev: &mut OtgFs, now: u128) -> Result<(), HostError> {
        let frame_start = self.slot % SLOTS_PER_FRAME == 0;
        match self.phase.clone() {
            Phase::Detached {
                until_ps,
                idle_since_ps,
            } => {
                if now >= idle_since_ps + 3 * MS {
                    dev.idle();
                }
                let plugged = until_ps.is_none_or(|u| now >= u);
                if plugged && dev.pullup() {
                    self.unplug_until_ps = None;
                    self.events
                        .push("USB host: device connected (D+ pull-up), debouncing 100 ms".into());
                    self.phase = Phase::Debounce {
                        until_ps: now + 100 * MS,
                    };
                }
                return Ok(());
            }
            Phase::Debounce { until_ps } => {
                if !dev.pullup() {
                    self.phase = Phase::Detached {
                        until_ps: None,
                        idle_since_ps: now,
                    };
                } else if now >= until_ps {
                    dev.bus_reset();
                    self.phase = Phase::Reset {
                        until_ps: now + 10 * MS,
                    };
                }
                return Ok(());
            }
            Phase::Reset { until_ps } => {
                if now >= until_ps {
                    dev.reset_end();
                    self.phase = Phase::Recovery {
                        until_ps: now + 10 * MS,
                    };
                }
                return Ok(());
            }
            Phase::Recovery { until_ps } => {
                if frame_start {
                    dev.frame();
                    self.frames += 1;
                }
                if now >= until_ps {
                    self.phase = Phase::Enumerating;
                    self.step = Step::DevHead;
                    self.addr = 0;
                    self.mps0 = 64;
                    self.device = None;
                    self.config = None;
                    self.dtr_sent = None;
                    self.out_packet = None;
                }
                return Ok(());
            }
            Phase::Enumerating | Phase::Running => {}
        }
        if !dev.pullup() {
            self.events
                .push("USB host: device disconnected (pull-up off)".into());
            self.phase = Phase::Detached {
                until_ps: None,
                idle_since_ps: now,
            };
            self.ctrl = None;
            return Ok(());
        }
        if frame_start {
            dev.frame();
            self.frames += 1;
        }
        if self.ctrl.is_none() && now >= self.wait_until_ps {
            if self.phase == Phase::Enumerating {
                self.issue(now);
            } else if self.dtr_sent != Some(self.dtr) {
                self.set_control_line_state(now);
                self.step = Step::SetControlLineState;
            }
        }
        if self.ctrl.is_some() {
            self.control(dev, now)?;
        }
        if self.phase == Phase::Running {
            self.data(dev, frame_start)?;
        }
        Ok(())
    }

    /// One transaction of the control transfer in progress.
    fn control(&mut self, dev: &mut OtgFs, now: u128) -> Result<(), HostError> {
        let Some(mut c) = self.ctrl.take() else {
            return Ok(());
        };
        let length = u16::from_le_bytes([c.setup[6], c.setup[7]]) as usize;
        let dir_in = c.setup[0] & 0x80 != 0;
        let limit_ms: u64 = if length == 0 { 50 } else { 5000 };
        if now > c.started_ps + limit_ms as u128 * MS {
            return Err(HostError::TimedOut {
                request: c.what,
                limit_ms,
            });
        }
        if dir_in && c.first_data_ps.is_none() && now > c.started_ps + 500 * MS {
            return Err(HostError::TimedOut {
                request: c.what,
                limit_ms: 500,
            });
        }
        let addr = self.addr;
        let r = match c.stage {
            Stage::Setup => dev.setup(addr, &c.setup),
            Stage::DataIn | Stage::StatusIn => dev.in_token(addr, 0),
            Stage::DataOut => {
                let end = (c.sent + self.mps0).min(c.out.len());
                dev.out(addr, 0, &c.out[c.sent..end])
            }
            Stage::StatusOut => dev.out(addr, 0, &[]),
        };
        match r {
            Handshake::Nak => {}
            Handshake::Stall => return Err(HostError::Stall { request: c.what }),
            Handshake::Timeout => {
                c.errors += 1;
                if c.errors >= 3 {
                    return Err(HostError::NoAnswer { request: c.what });
                }
            }
            Handshake::Ack(bytes) => {
                c.errors = 0;
                match c.stage {
                    Stage::Setup => {
                        c.stage = match (length, dir_in) {
                            (0, _) => Stage::StatusIn,
                            (_, true) => Stage::DataIn,
                            (_, false) => Stage::DataOut,
                        }
                    }
                    Stage::DataIn => {
                        c.first_data_ps.get_or_insert(now);
                        if bytes.len() > self.mps0 || c.got.len() + bytes.len() > length {
                            return Err(HostError::Protocol {
                                request: c.what,
                                what: format!(
                                    "babble: a {} B packet (EP0 {} B, {} of {length} B so far)",
                                    bytes.len(),
                                    self.mps0,
                                    c.got.len()
                                ),
                            });
                        }
                        let short = bytes.len() < self.mps0;
                        c.got.extend_from_slice(&bytes);
                        if short || c.got.len() == length {
                            c.stage = Stage::StatusOut;
                        }
                    }
                    Stage::DataOut => {
                        c.sent = (c.sent + self.mps0).min(c.out.len());
                        if c.sent >= c.out.len() {
                            c.stage = Stage::StatusIn;
                        }
                    }
                    Stage::StatusIn => {
                        if !bytes.is_empty() {
                            return Err(HostError::Protocol {
                                request: c.what,
                                what: format!(
                                    "{} B in the status stage (a zero-length packet expected)",
                                    bytes.len()
                                ),
                            });
                        }
                        let what = c.what;
                        return self.done(what, c.got, now);
                    }
                    Stage::StatusOut => {
                        let what = c.what;
                        return self.done(what, c.got, now);
                    }
                }
            }
        }
        self.ctrl = Some(c);
        Ok(())
    }

    /// The CDC data pipes: one bulk OUT and one bulk IN transaction, the
    /// notification endpoint at its interval.
    fn data(&mut self, dev: &mut OtgFs, frame_start: bool) -> Result<(), HostError> {
        let Some(cfg) = self.config.clone() else {
            return Ok(());
        };
        let acm = &cfg.acm;
        let addr = self.addr;
        if self.out_packet.is_none() && !self.out_queue.is_empty() {
            let n = self
                .out_queue
                .len()
                .min(acm.bulk_out.max_packet_size as usize);
            self.out_packet = Some(self.out_queue.drain(..n).collect());
        }
        if let Some(p) = &self.out_packet {
            match dev.out(addr, (acm.bulk_out.address & 0xF) as usize, p) {
                Handshake::Ack(_) => {
                    self.out_bytes += p.len() as u64;
                    self.out_packet = None;
                    self.out_errors = 0;
                }
                Handshake::Nak => {}
                Handshake::Stall => {
                    return Err(HostError::Stall {
                        request: "bulk OUT",
                    })
                }
                Handshake::Timeout => {
                    self.out_errors += 1;
                    if self.out_errors >= 3 {
                        return Err(HostError::NoAnswer {
                            request: "bulk OUT",
                        });
                    }
                }
            }
        }
        if self.reading && self.in_data.len() < IN_THROTTLE_BYTES {
            match dev.in_token(addr, (acm.bulk_in.address & 0xF) as usize) {
                Handshake::Ack(b) => {
                    if b.len() > acm.bulk_in.max_packet_size as usize {
                        return Err(HostError::Protocol {
                            request: "bulk IN",
                            what: format!(
                                "babble: {} B in a {} B endpoint",
                                b.len(),
                                acm.bulk_in.max_packet_size
                            ),
                        });
                    }
                    self.in_bytes += b.len() as u64;
                    self.in_data.extend_from_slice(&b);
                }
                Handshake::Nak => {}
                Handshake::Stall => return Err(HostError::Stall { request: "bulk IN" }),
                Handshake::Timeout => return Err(HostError::NoAnswer { request: "bulk IN" }),
            }
        }
        if frame_start && self.frames % acm.notify.interval.max(1) as u64 == 0 {
            match dev.in_token(addr, (acm.notify.address & 0xF) as usize) {
                Handshake::Ack(b) => self.events.push(format!("USB host: notification {b:02X?}")),
                Handshake::Nak => {}
                Handshake::Stall => {
                    return Err(HostError::Stall {
                        request: "notification IN",
                    })
                }
                Handshake::Timeout => {
                    return Err(HostError::NoAnswer {
                        request: "notification IN",
                    })
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device whose core is connected (pull-up on) but whose firmware
    /// never answers: the host debounces 100 ms before the reset, accepts
    /// the SETUP (the core always does), then fails the request after the
    /// 500 ms first-data limit of §9.2.6.4, naming it.
    #[test]
    fn silent_device_times_out_naming_the_request() {
        let mut d = OtgFs::new();
        d.write(0x00C, 1 << 30, !0).unwrap();
        d.write(0x038, (1 << 16) | (1 << 21), !0).unwrap();
        d.write(0x800, 3, !0).unwrap();
        d.write(0x024, 64, !0).unwrap();
        d.write(0x028, (16 << 16) | 64, !0).unwrap();
        let mut h = UsbHost::new();
        h.sync(&mut d, 99 * MS).unwrap();
        assert_eq!(d.stats.bus_resets, 0, "reset before the 100 ms debounce");
        h.sync(&mut d, 101 * MS).unwrap();
        assert_eq!(d.stats.bus_resets, 1);
        let mut t = 101 * MS;
        let e = loop {
            t += MS;
            if let Err(e) = h.sync(&mut d, t) {
                break e;
            }
            assert!(t < 2000 * MS, "no timeout");
        };
        assert_eq!(d.stats.setups, 1);
        match &e {
            HostError::TimedOut { request, limit_ms } => {
                assert!(request.contains("GET_DESCRIPTOR(DEVICE"), "{e}");
                assert_eq!(*limit_ms, 500);
            }
            _ => panic!("{e}"),
        }
        // Reset 100 ms + 10 ms recovery, then 500 ms for the first data.
        let t_s = t as f64 / (1000 * MS) as f64;
        assert!((0.61..0.63).contains(&t_s), "timed out at {t_s} s");
    }

    /// Bytes written while the device is not configured are lost (a
    /// vanished /dev/ttyACM0), not delivered late.
    #[test]
    fn bytes_before_configuration_are_lost() {
        let mut h = UsbHost::new();
        h.send(b"hello");
        assert_eq!(h.lost_bytes, 5);
        assert_eq!(h.out_pending(), 0);
    }
}
