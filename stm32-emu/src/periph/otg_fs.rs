//! USB OTG_FS in device mode (RM0383 §22, the Synopsys core of the F411;
//! the USB side from USB 2.0 ch. 8-9): the registers the image touches,
//! the shared RX FIFO with its status entries (GRXSTSR/GRXSTSP), one TX
//! FIFO per IN endpoint (DIEPTXFx, DTXFSTS, TXFE), endpoint control with
//! NAK/STALL/EPENA/USBAEP, transfer sizes and packet counts, the device
//! address (DCFG.DAD, effective after the SET_ADDRESS status stage), the
//! core and endpoint interrupts (GINTSTS/GINTMSK, DAINT/DAINTMSK,
//! DIEPINT/DIEPMSK/DIEPEMPMSK, DOEPINT/DOEPMSK) and the global interrupt
//! line, the soft connect (GCCFG.PWRDWN, DCTL.SDIS, GUSBCFG.FDMOD with
//! VBUS sensing off: GCCFG.NOVBUSSENS), bus reset, enumeration done,
//! suspend (3 ms idle) and wake-up, SOF/EOPF with the frame number.
//!
//! The host side is [`OtgFs::setup`], [`OtgFs::out`], [`OtgFs::in_token`]
//! (one transaction each, answered as the core answers: ACK, NAK, STALL,
//! or no answer), [`OtgFs::bus_reset`], [`OtgFs::frame`] and
//! [`OtgFs::idle`]: the host model (`crate::usb_host`) drives them.
//!
//! Not modelled: host mode, OTG (SRP/HNP), isochronous endpoints, data
//! toggles (DATA0/DATA1 are not checked or generated: a lost handshake,
//! which the toggle protects against, never happens here), DMA, LPM,
//! remote wake-up signalling (RWUSIG is stored), the PHY's timing within a
//! frame. An access to any other register fails the run.

use super::{merge, Access};
use std::collections::VecDeque;

/// Endpoints of the F411's OTG_FS (RM0383 §22.3: 3 IN + 3 OUT + EP0).
pub const EPS: usize = 4;
/// The data FIFO RAM \[32-bit words\] (RM0383 §22.11: 1.25 KB).
pub const FIFO_WORDS: u32 = 320;
/// CID's reset value (RM0383 §22.16.2, OTG_FS_CID: product ID 0x1200).
pub const CID: u32 = 0x0000_1200;

/// GINTSTS bits (RM0383 §22.16.2).
pub mod gint {
    /// Current mode (1 = host).
    pub const CMOD: u32 = 1 << 0;
    /// OTG interrupt.
    pub const OTGINT: u32 = 1 << 2;
    /// Start of frame.
    pub const SOF: u32 = 1 << 3;
    /// RX FIFO non-empty.
    pub const RXFLVL: u32 = 1 << 4;
    /// Non-periodic TX FIFO empty (host mode; reads 1 at reset).
    pub const NPTXFE: u32 = 1 << 5;
    /// Early suspend.
    pub const ESUSP: u32 = 1 << 10;
    /// USB suspend.
    pub const USBSUSP: u32 = 1 << 11;
    /// USB reset.
    pub const USBRST: u32 = 1 << 12;
    /// Enumeration done.
    pub const ENUMDNE: u32 = 1 << 13;
    /// End of periodic frame.
    pub const EOPF: u32 = 1 << 15;
    /// IN endpoint interrupt.
    pub const IEPINT: u32 = 1 << 18;
    /// OUT endpoint interrupt.
    pub const OEPINT: u32 = 1 << 19;
    /// Periodic TX FIFO empty (host mode; reads 1 at reset).
    pub const PTXFE: u32 = 1 << 26;
    /// Session request / new session detected.
    pub const SRQINT: u32 = 1 << 30;
    /// Resume / remote wake-up detected.
    pub const WKUPINT: u32 = 1 << 31;
    /// The bits cleared by writing 1 (rc_w1).
    pub const W1C: u32 = 0xF030_FC0A;
}

/// Endpoint control bits (DIEPCTLx / DOEPCTLx).
pub mod epctl {
    /// USB active endpoint.
    pub const USBAEP: u32 = 1 << 15;
    /// NAK status.
    pub const NAKSTS: u32 = 1 << 17;
    /// STALL handshake.
    pub const STALL: u32 = 1 << 21;
    /// Clear NAK (write only).
    pub const CNAK: u32 = 1 << 26;
    /// Set NAK (write only).
    pub const SNAK: u32 = 1 << 27;
    /// Endpoint disable.
    pub const EPDIS: u32 = 1 << 30;
    /// Endpoint enable.
    pub const EPENA: u32 = 1 << 31;
    /// The write-only bits (SD0PID, SODDFRM/SD1PID, SNAK, CNAK) and
    /// EPDIS (the core clears it at once here).
    pub const WRITE_ONLY: u32 = 0x7C00_0000;
}

/// A transaction's handshake from the device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Handshake {
    /// Accepted (OUT/SETUP) or data sent (IN, with the bytes).
    Ack(Vec<u8>),
    /// Not ready: the host retries.
    Nak,
    /// Endpoint halted or request not supported.
    Stall,
    /// No answer (not connected, another address, a full RX FIFO for a
    /// SETUP): the host counts an error.
    Timeout,
}

#[derive(Clone, Debug, Default)]
struct InEp {
    ctl: u32,
    int: u32,
    tsiz: u32,
    fifo: VecDeque<u32>,
}

#[derive(Clone, Debug, Default)]
struct OutEp {
    ctl: u32,
    int: u32,
    tsiz: u32,
}

/// RX FIFO status entry types (GRXSTSP.PKTSTS, device mode).
const PKT_OUT_DATA: u32 = 2;
const PKT_OUT_DONE: u32 = 3;
const PKT_SETUP_DONE: u32 = 4;
const PKT_SETUP_DATA: u32 = 6;

/// Counters (the summary and the checks).
#[derive(Clone, Debug, Default)]
pub struct UsbStats {
    /// IN tokens NAKed (nothing to send).
    pub in_naks: u64,
    /// OUT tokens NAKed (endpoint NAKing or RX FIFO full: held off).
    pub out_naks: u64,
    /// IN data packets sent on the bulk/interrupt endpoints.
    pub in_packets: u64,
    /// OUT data packets accepted on the bulk endpoints.
    pub out_packets: u64,
    /// SETUP packets accepted.
    pub setups: u64,
    /// Bus resets.
    pub bus_resets: u64,
}

/// The OTG_FS core.
#[derive(Clone, Debug)]
pub struct OtgFs {
    gotgctl: u32,
    gotgint: u32,
    gahbcfg: u32,
    gusbcfg: u32,
    gint_latched: u32,
    gintmsk: u32,
    grxfsiz: u32,
    dieptxf: [u32; EPS],
    gccfg: u32,
    dcfg: u32,
    dctl: u32,
    diepmsk: u32,
    doepmsk: u32,
    daintmsk: u32,
    diepempmsk: u32,
    pcgcctl: u32,
    /// DSTS.ENUMSPD after enumeration (3: full speed, 48 MHz PHY clock).
    enumspd: u32,
    suspended: bool,
    fnsof: u32,
    ine: [InEp; EPS],
    oute: [OutEp; EPS],
    /// Status entries with their data words.
    rx: VecDeque<(u32, Vec<u32>)>,
    /// The data words of the entry last popped, not yet read.
    rx_cur: VecDeque<u32>,
    /// The address the core answers to (DAD takes effect after the
    /// SET_ADDRESS status stage).
    addr: u8,
    addr_pending: Option<u8>,
    /// Counters.
    pub stats: UsbStats,
}

impl Default for OtgFs {
    fn default() -> Self {
        Self::new()
    }
}

fn ep0_mps(ctl: u32) -> usize {
    [64, 32, 16, 8][(ctl & 3) as usize]
}

impl OtgFs {
    /// After reset (RM0383 §22.16 reset values).
    pub fn new() -> Self {
        let mut s = Self {
            gotgctl: 0x0001_0000,
            gotgint: 0,
            gahbcfg: 0,
            gusbcfg: 0x0000_0A00,
            gint_latched: 0,
            gintmsk: 0,
            grxfsiz: 0x200,
            dieptxf: [0x0200_0200; EPS],
            gccfg: 0,
            dcfg: 0x0220_0000,
            dctl: 0,
            diepmsk: 0,
            doepmsk: 0,
            daintmsk: 0,
            diepempmsk: 0,
            pcgcctl: 0,
            enumspd: 0,
            suspended: false,
            fnsof: 0,
            ine: Default::default(),
            oute: Default::default(),
            rx: VecDeque::new(),
            rx_cur: VecDeque::new(),
            addr: 0,
            addr_pending: None,
            stats: UsbStats::default(),
        };
        // EP0 is always active (USBAEP reads 1).
        s.ine[0].ctl = epctl::USBAEP;
        s.oute[0].ctl = epctl::USBAEP;
        s
    }

    /// The D+ pull-up is on: the transceiver powered (GCCFG.PWRDWN),
    /// device mode forced (GUSBCFG.FDMOD), not soft-disconnected
    /// (DCTL.SDIS), and the B-session valid without VBUS sensing
    /// (GCCFG.NOVBUSSENS: the board does not wire VBUS to PA9).
    pub fn pullup(&self) -> bool {
        self.gccfg & (1 << 16) != 0
            && self.gccfg & (1 << 21) != 0
            && self.gusbcfg & (1 << 30) != 0
            && self.dctl & 2 == 0
    }

    /// The device address the core answers to.
    pub fn address(&self) -> u8 {
        self.addr
    }

    fn iep_mask(&self, n: usize) -> u32 {
        let txfe = if self.diepempmsk & (1 << n) != 0 {
            1 << 7
        } else {
            0
        };
        (self.diepmsk & !(1 << 7)) | txfe
    }

    fn diepint(&self, n: usize) -> u32 {
        let e = &self.ine[n];
        let fd = self.fifo_depth(n) as usize;
        // TXFE: half empty (GAHBCFG.TXFELVL = 0) or completely empty.
        let level = if self.gahbcfg & (1 << 7) != 0 {
            e.fifo.is_empty()
        } else {
            e.fifo.len() * 2 <= fd
        };
        e.int | if level { 1 << 7 } else { 0 }
    }

    fn daint(&self) -> u32 {
        let mut v = 0;
        for n in 0..EPS {
            if self.diepint(n) & self.iep_mask(n) != 0 {
                v |= 1 << n;
            }
            if self.oute[n].int & self.doepmsk != 0 {
                v |= 1 << (16 + n);
            }
        }
        v
    }

    fn gintsts(&self) -> u32 {
        let daint = self.daint() & self.daintmsk;
        let mut v = self.gint_latched | gint::NPTXFE | gint::PTXFE;
        if !self.rx.is_empty() {
            v |= gint::RXFLVL;
        }
        if daint & 0xFFFF != 0 {
            v |= gint::IEPINT;
        }
        if daint >> 16 != 0 {
            v |= gint::OEPINT;
        }
        v
    }

    /// The OTG_FS global interrupt line (GAHBCFG.GINT and an unmasked
    /// GINTSTS bit).
    pub fn irq(&self) -> bool {
        self.gahbcfg & 1 != 0 && self.gintsts() & self.gintmsk != 0
    }

    fn fifo_depth(&self, n: usize) -> u32 {
        self.dieptxf[n] >> 16
    }

    fn rx_used_words(&self) -> usize {
        self.rx.iter().map(|e| 1 + e.1.len()).sum::<usize>() + self.rx_cur.len()
    }

    fn rx_room(&self, words: usize) -> bool {
        self.rx_used_words() + words <= (self.grxfsiz & 0xFFFF) as usize
    }

    fn words(data: &[u8]) -> Vec<u32> {
        data.chunks(4)
            .map(|c| {
                let mut w = [0u8; 4];
                w[..c.len()].copy_from_slice(c);
                u32::from_le_bytes(w)
            })
            .collect()
    }

    fn status(ep: usize, bcnt: usize, pktsts: u32) -> u32 {
        ep as u32 | ((bcnt as u32) << 4) | (pktsts << 17)
    }

    fn answers(&self, addr: u8) -> bool {
        self.pullup() && self.enumspd != 0 && addr == self.addr
    }

    /// The host's bus reset starts (SE0 for at least 10 ms, USB 2.0
    /// §7.1.7.5): USBRST; the core answers nothing until
    /// [`Self::reset_end`], then at address 0; USBAEP of every endpoint
    /// but EP0 is cleared (RM0383 §22.16.4, DIEPCTLx/DOEPCTLx USBAEP). A
    /// reset that ends a suspend also signals the wake-up.
    pub fn bus_reset(&mut self) {
        self.stats.bus_resets += 1;
        if self.suspended {
            self.suspended = false;
            self.gint_latched |= gint::WKUPINT;
        }
        self.gint_latched |= gint::USBRST;
        self.enumspd = 0;
        self.addr = 0;
        self.addr_pending = None;
        for n in 1..EPS {
            self.ine[n].ctl &= !epctl::USBAEP;
            self.oute[n].ctl &= !epctl::USBAEP;
        }
    }

    /// The bus reset ends: enumeration done (ENUMDNE), full speed
    /// (DSTS.ENUMSPD = 3).
    pub fn reset_end(&mut self) {
        self.gint_latched |= gint::ENUMDNE;
        self.enumspd = 3;
    }

    /// A frame starts (SOF from the host, every 1 ms): SOF and the end of
    /// the previous frame (EOPF), the frame number; a suspended device
    /// resumes (WKUPINT).
    pub fn frame(&mut self) {
        if !self.pullup() || self.enumspd == 0 {
            return;
        }
        if self.suspended {
            self.suspended = false;
            self.gint_latched |= gint::WKUPINT;
        }
        self.fnsof = (self.fnsof + 1) & 0x3FFF;
        self.gint_latched |= gint::SOF | gint::EOPF;
    }

    /// The bus has been idle for 3 ms (no SOF: the host suspended it or
    /// the cable is out, USB 2.0 §7.1.7.6): early suspend and suspend.
    pub fn idle(&mut self) {
        if !self.suspended && self.enumspd != 0 {
            self.suspended = true;
            self.gint_latched |= gint::ESUSP | gint::USBSUSP;
        }
    }

    /// A SETUP transaction to `addr`, endpoint 0. The core always accepts
    /// a SETUP (USB 2.0 §8.5.3) when the RX FIFO has room for it: two
    /// entries (the 8 data bytes, then "SETUP stage done", whose pop sets
    /// DOEPINT0.STUP); STALL on EP0 is cleared.
    pub fn setup(&mut self, addr: u8, data: &[u8; 8]) -> Handshake {
        if !self.answers(addr) || !self.rx_room(4) {
            return Handshake::Timeout;
        }
        self.stats.setups += 1;
        self.ine[0].ctl &= !epctl::STALL;
        self.oute[0].ctl &= !epctl::STALL;
        self.rx
            .push_back((Self::status(0, 8, PKT_SETUP_DATA), Self::words(data)));
        self.rx
            .push_back((Self::status(0, 0, PKT_SETUP_DONE), Vec::new()));
        let stupcnt = (self.oute[0].tsiz >> 29) & 3;
        self.oute[0].tsiz = (self.oute[0].tsiz & !(3 << 29)) | (stupcnt.saturating_sub(1) << 29);
        Handshake::Ack(Vec::new())
    }

    /// An OUT transaction with `data` to endpoint `ep` of `addr`: STALL if
    /// halted; NAK while the endpoint NAKs (NAKSTS) or the RX FIFO has no
    /// room; else ACK, the packet into the RX FIFO, and when the transfer
    /// ends (its packet count reaches 0, or a short packet) the "transfer
    /// completed" entry and NAK set: the application clears NAK (CNAK)
    /// when it can take the next packet.
    pub fn out(&mut self, addr: u8, ep: usize, data: &[u8]) -> Handshake {
        if ep >= EPS || !self.answers(addr) {
            return Handshake::Timeout;
        }
        let e = &self.oute[ep];
        let mps = if ep == 0 {
            ep0_mps(e.ctl)
        } else {
            (e.ctl & 0x7FF) as usize
        };
        if e.ctl & epctl::USBAEP == 0 {
            return Handshake::Timeout;
        }
        if e.ctl & epctl::STALL != 0 {
            return Handshake::Stall;
        }
        if data.len() > mps {
            // Babble: the host model never sends more than wMaxPacketSize.
            return Handshake::Timeout;
        }
        let words = data.len().div_ceil(4);
        if e.ctl & epctl::NAKSTS != 0 || !self.rx_room(1 + words + 1) {
            self.stats.out_naks += 1;
            return Handshake::Nak;
        }
        self.rx.push_back((
            Self::status(ep, data.len(), PKT_OUT_DATA),
            Self::words(data),
        ));
        let e = &mut self.oute[ep];
        let (pkt_shift, pkt_mask, xfr_mask) = if ep == 0 {
            (19, 1, 0x7F)
        } else {
            (19, 0x3FF, 0x7FFFF)
        };
        let pktcnt = (e.tsiz >> pkt_shift) & pkt_mask;
        let xfrsiz = e.tsiz & xfr_mask;
        let pktcnt = pktcnt.saturating_sub(1);
        let xfrsiz = xfrsiz.saturating_sub(data.len() as u32);
        e.tsiz = (e.tsiz & !((pkt_mask << pkt_shift) | xfr_mask)) | (pktcnt << pkt_shift) | xfrsiz;
        if pktcnt == 0 || data.len() < mps {
            self.rx
                .push_back((Self::status(ep, 0, PKT_OUT_DONE), Vec::new()));
            e.ctl |= epctl::NAKSTS;
            e.ctl &= !epctl::EPENA;
        }
        if ep != 0 {
            self.stats.out_packets += 1;
        }
        Handshake::Ack(Vec::new())
    }

    /// An IN token to endpoint `ep` of `addr`: STALL if halted; NAK unless
    /// the endpoint is enabled (EPENA), not NAKing, and its TX FIFO holds
    /// the whole next packet; else the packet (min(wMaxPacketSize,
    /// XFRSIZ left) bytes), the counts decremented, and at the transfer's
    /// end XFRC with EPENA cleared. The status stage of a SET_ADDRESS (a
    /// zero-length IN on EP0) makes DCFG.DAD the address.
    pub fn in_token(&mut self, addr: u8, ep: usize) -> Handshake {
        if ep >= EPS || !self.answers(addr) {
            return Handshake::Timeout;
        }
        let e = &mut self.ine[ep];
        if e.ctl & epctl::USBAEP == 0 {
            return Handshake::Timeout;
        }
        if e.ctl & epctl::STALL != 0 {
            return Handshake::Stall;
        }
        let (mps, pkt_mask, xfr_mask) = if ep == 0 {
            (ep0_mps(e.ctl), 3, 0x7F)
        } else {
            ((e.ctl & 0x7FF) as usize, 0x3FF, 0x7FFFF)
        };
        let xfrsiz = (e.tsiz & xfr_mask) as usize;
        let pktcnt = (e.tsiz >> 19) & pkt_mask;
        let len = xfrsiz.min(mps);
        let words = len.div_ceil(4);
        if e.ctl & epctl::EPENA == 0
            || e.ctl & epctl::NAKSTS != 0
            || pktcnt == 0
            || e.fifo.len() < words
        {
            self.stats.in_naks += 1;
            return Handshake::Nak;
        }
        let mut bytes = Vec::with_capacity(words * 4);
        for _ in 0..words {
            bytes.extend_from_slice(&e.fifo.pop_front().unwrap_or(0).to_le_bytes());
        }
        bytes.truncate(len);
        let pktcnt = pktcnt - 1;
        let xfrsiz = xfrsiz - len;
        e.tsiz = (e.tsiz & !((pkt_mask << 19) | xfr_mask)) | (pktcnt << 19) | xfrsiz as u32;
        if pktcnt == 0 {
            e.ctl &= !epctl::EPENA;
            e.int |= 1; // XFRC
        }
        if ep == 0 && len == 0 {
            if let Some(a) = self.addr_pending.take() {
                self.addr = a;
            }
        }
        if ep != 0 {
            self.stats.in_packets += 1;
        }
        Handshake::Ack(bytes)
    }

    /// Reads the register at `off` (0..0x2_0000 of the OTG_FS block).
    pub fn read(&mut self, off: u32) -> Access<u32> {
        Ok(match off {
            0x000 => self.gotgctl,
            0x004 => self.gotgint,
            0x008 => self.gahbcfg,
            0x00C => self.gusbcfg,
            // AHBIDL; resets and flushes complete at once.
            0x010 => 1 << 31,
            0x014 => self.gintsts(),
            0x018 => self.gintmsk,
            0x01C => self.rx.front().map_or(0, |e| e.0),
            0x020 => {
                if !self.rx_cur.is_empty() {
                    return Err(format!(
                        "USB_OTG_FS GRXSTSP popped with {} data words of the previous packet unread (RM0383 §22.17.6: the application must read them first)",
                        self.rx_cur.len()
                    ));
                }
                let Some((st, data)) = self.rx.pop_front() else {
                    return Err(
                        "USB_OTG_FS GRXSTSP popped with the RX FIFO empty (RXFLVL = 0)".into(),
                    );
                };
                let ep = (st & 0xF) as usize;
                match (st >> 17) & 0xF {
                    PKT_SETUP_DONE => self.oute[ep].int |= 1 << 3, // STUP
                    PKT_OUT_DONE => self.oute[ep].int |= 1,        // XFRC
                    _ => {}
                }
                self.rx_cur = data.into();
                st
            }
            0x024 => self.grxfsiz,
            0x028 => self.dieptxf[0],
            0x038 => self.gccfg,
            0x03C => CID,
            // GHWCFG4 (not in RM0383: the Synopsys core's hardware
            // configuration). embassy reads its PHY data width, used only
            // for an internal high-speed PHY: the F411's FS core reads 0.
            0x050 => 0,
            0x104 | 0x108 | 0x10C => self.dieptxf[((off - 0x100) / 4) as usize],
            0x800 => self.dcfg,
            0x804 => self.dctl,
            0x808 => (self.suspended as u32) | (self.enumspd << 1) | (self.fnsof << 8),
            0x810 => self.diepmsk,
            0x814 => self.doepmsk,
            0x818 => self.daint(),
            0x81C => self.daintmsk,
            0x834 => self.diepempmsk,
            0x900..=0x9FF => {
                let n = ((off - 0x900) / 0x20) as usize;
                if n >= EPS {
                    return Err(format!(
                        "USB_OTG_FS +0x{off:03X} (IN endpoint {n}: the F411 has 4)"
                    ));
                }
                match off & 0x1F {
                    0x00 => self.ine[n].ctl,
                    0x08 => self.diepint(n),
                    0x10 => self.ine[n].tsiz,
                    0x18 => self
                        .fifo_depth(n)
                        .saturating_sub(self.ine[n].fifo.len() as u32),
                    r => return Err(format!("USB_OTG_FS DIEP{n} +0x{r:02X}")),
                }
            }
            0xB00..=0xBFF => {
                let n = ((off - 0xB00) / 0x20) as usize;
                if n >= EPS {
                    return Err(format!(
                        "USB_OTG_FS +0x{off:03X} (OUT endpoint {n}: the F411 has 4)"
                    ));
                }
                match off & 0x1F {
                    0x00 => self.oute[n].ctl,
                    0x08 => self.oute[n].int,
                    0x10 => self.oute[n].tsiz,
                    r => return Err(format!("USB_OTG_FS DOEP{n} +0x{r:02X}")),
                }
            }
            0xE00 => self.pcgcctl,
            0x1000..=0x4FFF => {
                // Any FIFO address pops the shared RX FIFO.
                match self.rx_cur.pop_front() {
                    Some(w) => w,
                    None => {
                        return Err(format!(
                            "USB_OTG_FS FIFO read at +0x{off:X} with no packet data popped (GRXSTSP first)"
                        ))
                    }
                }
            }
            _ => return Err(Self::name(off)),
        })
    }

    fn name(off: u32) -> String {
        let reg = match off {
            0x02C => " HNPTXSTS",
            0x030 => " GI2CCTL",
            0x100 => " HPTXFSIZ",
            0x400..=0x7FF => " (host registers)",
            0x80C => " (reserved)",
            0x828 => " DVBUSDIS",
            0x82C => " DVBUSPULSE",
            _ => "",
        };
        format!("USB_OTG_FS +0x{off:X}{reg}")
    }

    /// Writes the register at `off` under the byte-lane `mask`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        let v = value & mask;
        match off {
            0x000 => self.gotgctl = merge(self.gotgctl, value, mask),
            0x004 => self.gotgint &= !v,
            0x008 => self.gahbcfg = merge(self.gahbcfg, value, mask),
            0x00C => {
                self.gusbcfg = merge(self.gusbcfg, value, mask);
                if self.gusbcfg & (1 << 29) != 0 {
                    return Err("USB_OTG_FS GUSBCFG.FHMOD: host mode not modelled".into());
                }
            }
            0x010 => {
                if v & 1 != 0 {
                    // Core soft reset: interrupts and FIFOs cleared, the
                    // CSR registers kept (RM0383 §22.16.2, CSRST).
                    self.gint_latched = 0;
                    self.rx.clear();
                    self.rx_cur.clear();
                    for e in &mut self.ine {
                        e.fifo.clear();
                    }
                }
                if v & (1 << 4) != 0 {
                    self.rx.clear();
                    self.rx_cur.clear();
                }
                if v & (1 << 5) != 0 {
                    let n = ((v >> 6) & 0x1F) as usize;
                    for (i, e) in self.ine.iter_mut().enumerate() {
                        if n == 0x10 || n == i {
                            e.fifo.clear();
                        }
                    }
                }
                if v & 0x6 != 0 {
                    return Err("USB_OTG_FS GRSTCTL HSRST/FCRST not modelled".into());
                }
            }
            0x014 => self.gint_latched &= !(v & gint::W1C),
            0x018 => self.gintmsk = merge(self.gintmsk, value, mask),
            0x024 => self.grxfsiz = merge(self.grxfsiz, value, mask) & 0xFFFF,
            0x028 | 0x104 | 0x108 | 0x10C => {
                let n = if off == 0x28 {
                    0
                } else {
                    ((off - 0x100) / 4) as usize
                };
                self.dieptxf[n] = merge(self.dieptxf[n], value, mask);
                let (sa, fd) = (self.dieptxf[n] & 0xFFFF, self.dieptxf[n] >> 16);
                if sa + fd > FIFO_WORDS || fd < 16 {
                    return Err(format!(
                        "USB_OTG_FS DIEPTXF{n} start {sa} depth {fd} words: beyond the {FIFO_WORDS}-word FIFO RAM or below the 16-word minimum (RM0383 §22.16.2)"
                    ));
                }
            }
            0x038 => self.gccfg = merge(self.gccfg, value, mask),
            0x800 => {
                self.dcfg = merge(self.dcfg, value, mask);
                if self.dcfg & 3 != 3 {
                    return Err(format!(
                        "USB_OTG_FS DCFG.DSPD = {}: only full speed (3) exists on OTG_FS",
                        self.dcfg & 3
                    ));
                }
                let dad = ((self.dcfg >> 4) & 0x7F) as u8;
                if dad != self.addr {
                    self.addr_pending = Some(dad);
                }
            }
            0x804 => {
                self.dctl = merge(self.dctl, value, mask)
                    & !((1 << 7) | (1 << 8) | (1 << 9) | (1 << 10) | (1 << 11));
                if self.dctl & (0x7 << 4) != 0 {
                    return Err("USB_OTG_FS DCTL.TCTL: test modes not modelled".into());
                }
            }
            0x810 => self.diepmsk = merge(self.diepmsk, value, mask),
            0x814 => self.doepmsk = merge(self.doepmsk, value, mask),
            0x81C => self.daintmsk = merge(self.daintmsk, value, mask),
            0x834 => self.diepempmsk = merge(self.diepempmsk, value, mask),
            0x900..=0x9FF => {
                let n = ((off - 0x900) / 0x20) as usize;
                if n >= EPS {
                    return Err(format!(
                        "USB_OTG_FS +0x{off:03X} (IN endpoint {n}: the F411 has 4)"
                    ));
                }
                match off & 0x1F {
                    0x00 => {
                        let e = &mut self.ine[n];
                        e.ctl = Self::ctl_write(e.ctl, value, mask, n, &mut e.int);
                        if n != 0 && (e.ctl >> 18) & 3 == 1 {
                            return Err(format!("USB_OTG_FS DIEPCTL{n}: isochronous not modelled"));
                        }
                    }
                    0x08 => self.ine[n].int &= !(v & 0x7B),
                    0x10 => self.ine[n].tsiz = merge(self.ine[n].tsiz, value, mask),
                    r => return Err(format!("USB_OTG_FS DIEP{n} +0x{r:02X}")),
                }
            }
            0xB00..=0xBFF => {
                let n = ((off - 0xB00) / 0x20) as usize;
                if n >= EPS {
                    return Err(format!(
                        "USB_OTG_FS +0x{off:03X} (OUT endpoint {n}: the F411 has 4)"
                    ));
                }
                match off & 0x1F {
                    0x00 => {
                        let e = &mut self.oute[n];
                        e.ctl = Self::ctl_write(e.ctl, value, mask, n, &mut e.int);
                        if n != 0 && (e.ctl >> 18) & 3 == 1 {
                            return Err(format!("USB_OTG_FS DOEPCTL{n}: isochronous not modelled"));
                        }
                    }
                    0x08 => self.oute[n].int &= !(v & 0x7B),
                    0x10 => self.oute[n].tsiz = merge(self.oute[n].tsiz, value, mask),
                    r => return Err(format!("USB_OTG_FS DOEP{n} +0x{r:02X}")),
                }
            }
            0xE00 => {
                self.pcgcctl = merge(self.pcgcctl, value, mask);
                if self.pcgcctl & 3 != 0 {
                    return Err(
                        "USB_OTG_FS PCGCCTL: clock gating (STPPCLK/GATEHCLK) not modelled".into(),
                    );
                }
            }
            0x1000..=0x4FFF => {
                let n = ((off - 0x1000) / 0x1000) as usize;
                let fd = self.fifo_depth(n) as usize;
                let e = &mut self.ine[n];
                if e.fifo.len() >= fd {
                    return Err(format!(
                        "USB_OTG_FS TX FIFO {n} written beyond its {fd} words (DTXFSTS{n} = 0): the word would be lost"
                    ));
                }
                e.fifo.push_back(v);
            }
            _ => return Err(Self::name(off)),
        }
        Ok(())
    }

    /// DIEPCTLx/DOEPCTLx write: SNAK/CNAK set/clear NAKSTS, EPDIS
    /// disables an enabled endpoint at once (EPDISD), EPENA set by the
    /// application only; EP0's USBAEP and EPTYP are fixed.
    fn ctl_write(old: u32, value: u32, mask: u32, n: usize, int: &mut u32) -> u32 {
        let v = value & mask;
        let keep = epctl::NAKSTS | epctl::EPENA | (1 << 16);
        let mut c = (merge(old, value, mask) & !(epctl::WRITE_ONLY | keep)) | (old & keep);
        if v & epctl::EPENA != 0 {
            c |= epctl::EPENA;
        }
        if v & epctl::SNAK != 0 {
            c |= epctl::NAKSTS;
        }
        if v & epctl::CNAK != 0 {
            c &= !epctl::NAKSTS;
        }
        if v & epctl::EPDIS != 0 && c & epctl::EPENA != 0 {
            c &= !epctl::EPENA;
            *int |= 1 << 1; // EPDISD
        }
        if n == 0 {
            c = (c | epctl::USBAEP) & !(3 << 18);
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A device configured as embassy's driver does it for EP0 (64 B) and
    /// a bulk pair on endpoint 1 (64 B), connected and reset.
    fn device() -> OtgFs {
        let mut d = OtgFs::new();
        d.write(0x00C, 1 << 30, !0).unwrap();
        d.write(0x038, (1 << 16) | (1 << 21), !0).unwrap();
        d.write(0x800, 3, !0).unwrap();
        d.write(0x024, 64, !0).unwrap();
        d.write(0x028, (16 << 16) | 64, !0).unwrap();
        d.write(0x104, (16 << 16) | 80, !0).unwrap();
        d.bus_reset();
        d.reset_end();
        d.write(0x920, epctl::USBAEP | (2 << 18) | 64 | epctl::SNAK, !0)
            .unwrap();
        d.write(0xB20, epctl::USBAEP | (2 << 18) | 64, !0).unwrap();
        d.write(0xB30, (1 << 19) | 64, !0).unwrap();
        d
    }

    /// OUT: accepted into the RX FIFO with its status entries, then NAKed
    /// until the application clears NAK (the flooding host held off);
    /// GRXSTSP's pop order and RXFLVL follow the FIFO.
    #[test]
    fn out_packet_then_nak_until_cnak() {
        let mut d = device();
        assert_eq!(d.out(0, 1, b"hello"), Handshake::Ack(vec![]));
        assert_eq!(
            d.out(0, 1, b"again"),
            Handshake::Nak,
            "NAK after the transfer"
        );
        assert_ne!(d.read(0x014).unwrap() & gint::RXFLVL, 0);
        let st = d.read(0x020).unwrap();
        assert_eq!((st & 0xF, (st >> 4) & 0x7FF, (st >> 17) & 0xF), (1, 5, 2));
        let w0 = d.read(0x1000).unwrap();
        let w1 = d.read(0x1000).unwrap();
        assert_eq!(&w0.to_le_bytes(), b"hell");
        assert_eq!(w1 & 0xFF, b'o' as u32);
        assert_eq!((d.read(0x020).unwrap() >> 17) & 0xF, 3);
        assert_eq!(d.read(0x014).unwrap() & gint::RXFLVL, 0);
        assert!(
            d.read(0x1000).is_err(),
            "a FIFO read with nothing popped fails"
        );
        d.write(0xB20, epctl::CNAK, epctl::CNAK).unwrap();
        assert_eq!(d.out(0, 1, b"again"), Handshake::Ack(vec![]));
    }

    /// IN: NAK until EPENA and the whole packet is in the FIFO; then the
    /// packet, XFRC, EPENA cleared; DTXFSTS counts free words.
    #[test]
    fn in_packet_needs_the_whole_packet() {
        let mut d = device();
        assert_eq!(d.in_token(0, 1), Handshake::Nak);
        d.write(0x930, (1 << 19) | 6, !0).unwrap();
        d.write(
            0x920,
            epctl::CNAK | epctl::EPENA,
            epctl::CNAK | epctl::EPENA,
        )
        .unwrap();
        d.write(0x2000, u32::from_le_bytes(*b"abcd"), !0).unwrap();
        assert_eq!(
            d.in_token(0, 1),
            Handshake::Nak,
            "half the packet in the FIFO"
        );
        assert_eq!(d.read(0x938).unwrap(), 15);
        d.write(0x2000, u32::from_le_bytes(*b"ef\0\0"), !0).unwrap();
        assert_eq!(d.in_token(0, 1), Handshake::Ack(b"abcdef".to_vec()));
        assert_eq!(d.read(0x920).unwrap() & epctl::EPENA, 0);
        assert_ne!(d.read(0x928).unwrap() & 1, 0, "XFRC");
        assert_eq!(d.in_token(0, 1), Handshake::Nak);
    }

    /// SET_ADDRESS: DAD written before the status stage takes effect after
    /// the zero-length IN; a bus reset clears USBAEP of endpoint 1 and the
    /// address.
    #[test]
    fn address_after_status_stage_and_reset() {
        let mut d = device();
        d.write(0x800, 3 | (5 << 4), !0).unwrap();
        assert_eq!(d.address(), 0);
        d.write(0x910, 1 << 19, !0).unwrap();
        d.write(0x900, epctl::EPENA | epctl::CNAK, !0).unwrap();
        assert_eq!(d.in_token(0, 0), Handshake::Ack(vec![]));
        assert_eq!(d.address(), 5);
        assert_eq!(d.in_token(0, 1), Handshake::Timeout, "old address");
        d.bus_reset();
        d.reset_end();
        assert_eq!(d.address(), 0);
        assert_eq!(d.read(0x920).unwrap() & epctl::USBAEP, 0);
        assert_eq!(d.in_token(0, 1), Handshake::Timeout, "inactive endpoint");
    }
}
