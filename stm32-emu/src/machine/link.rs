//! The host link's two transports on the board: USART2 (F446) and USB
//! OTG_FS with the host on the cable (F411). The pty side
//! (`main.rs`) moves bytes through [`Board::link_from_host`] and
//! [`Board::link_to_host`] whichever the chip.

use super::{Board, ChipKind};

/// USB needs its 48 MHz clock within ±0.25 % (USB 2.0 §7.1.11: 12 Mb/s
/// ±0.25 % at full speed).
const USB_CLOCK_TOLERANCE: f64 = 0.0025;

/// The host's write buffer for the bulk OUT endpoint \[B\] (Linux's
/// tty layer holds a few kB before a writer blocks).
pub const HOST_OUT_BUFFER_BYTES: usize = 4096;

impl Board {
    /// Runs the USB host's slots up to now (F411); a host failure ends
    /// the run with its reason.
    pub(super) fn sync_usb(&mut self) -> Result<(), String> {
        let Some(h) = self.usb_host.as_mut() else {
            return Ok(());
        };
        let now = self.base_ps
            + (self.cycles - self.base_cycles) as u128 * crate::periph::PS_PER_S
                / self.sysclk_hz as u128;
        if h.next_event_ps() > now {
            return Ok(());
        }
        if self.usb.pullup() {
            let hz = self.rcc.pll48_hz();
            if (hz as f64 / 48e6 - 1.0).abs() > USB_CLOCK_TOLERANCE {
                return Err(format!(
                    "USB OTG_FS connected with its 48 MHz clock (PLL48CLK) at {hz} Hz: beyond ±0.25 % (USB 2.0 §7.1.11)"
                ));
            }
        }
        let r = h.sync(&mut self.usb, now);
        let events = std::mem::take(&mut h.events);
        for e in events {
            self.event(e);
        }
        r.map_err(|e| e.to_string())
    }

    /// Bytes from the host program (the pty) towards the firmware.
    pub fn link_from_host(&mut self, bytes: &[u8]) {
        let now = self.now_ps();
        if !bytes.is_empty() {
            self.last_host_byte_ps = Some(now);
        }
        match (self.chip, self.usb_host.as_mut()) {
            (ChipKind::F411ce, Some(h)) => h.send(bytes),
            _ => self.usart2.host_send(bytes, now),
        }
    }

    /// The link takes more bytes from the host program now (USB: fewer
    /// than [`HOST_OUT_BUFFER_BYTES`] queued for bulk OUT; USART2: always,
    /// a UART has no flow control here).
    pub fn link_has_room(&self) -> bool {
        self.usb_host
            .as_ref()
            .is_none_or(|h| h.out_pending() < HOST_OUT_BUFFER_BYTES)
    }

    /// Bytes the firmware sent to the host program since the last call.
    pub fn link_to_host(&mut self) -> Vec<u8> {
        match (self.chip, self.usb_host.as_mut()) {
            (ChipKind::F411ce, Some(h)) => std::mem::take(&mut h.in_data),
            _ => std::mem::take(&mut self.usart2.tx_out),
        }
    }
}
