//! The host link's byte path: two bounded pipes between the port's task
//! and the control task.
//!
//! The control task owns the protocol handler ([`Device`]); the port side
//! (a UART task, a USB class, the emulated UART) only moves bytes. Neither
//! side waits on the other in the control task: [`LinkPipes::receive`] and
//! [`LinkPipes::transmit`] move at most what fits, so a silent host, a
//! flooding host or a host that stops reading never delays a tick. When the
//! host floods, the receive pipe fills and the port task drops (and counts)
//! the excess ([`LinkPipes::rx_dropped_bytes`]); the frames that lost bytes
//! then fail their CRC and the device counts them. When the host stops
//! reading, the send pipe fills and the device drops (and counts) telemetry.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use wmr_device::Device;

/// Bytes each pipe holds.
pub const PIPE_BYTES: usize = 512;
/// Bytes the control task moves out per tick at most (its stack buffer).
pub const TX_BYTES_PER_TICK: usize = 128;

/// Host → robot and robot → host byte pipes (put them in a `static`).
pub struct LinkPipes {
    rx: Pipe<CriticalSectionRawMutex, PIPE_BYTES>,
    tx: Pipe<CriticalSectionRawMutex, PIPE_BYTES>,
    rx_dropped: AtomicU32,
}

impl Default for LinkPipes {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkPipes {
    /// Empty pipes.
    pub const fn new() -> Self {
        Self {
            rx: Pipe::new(),
            tx: Pipe::new(),
            rx_dropped: AtomicU32::new(0),
        }
    }

    /// Control task, before the tick: received bytes into the device (at
    /// most what it accepts and [`wmr_device::RX_BYTES_PER_TICK`]). Returns
    /// the bytes moved.
    pub fn receive<const H: usize>(&self, dev: &mut Device<H>) -> usize {
        let mut buf = [0u8; wmr_device::RX_BYTES_PER_TICK];
        let room = dev.rx_free().min(buf.len());
        if room == 0 {
            return 0;
        }
        match self.rx.try_read(&mut buf[..room]) {
            Ok(n) => dev.push_rx(&buf[..n]),
            Err(_) => 0, // empty
        }
    }

    /// Control task, after the tick: queued frames out (at most what the
    /// pipe has room for and [`TX_BYTES_PER_TICK`]). Returns the bytes moved.
    pub fn transmit<const H: usize>(&self, dev: &mut Device<H>) -> usize {
        let mut buf = [0u8; TX_BYTES_PER_TICK];
        let room = self.tx.free_capacity().min(buf.len());
        let n = dev.pop_tx(&mut buf[..room]);
        // Fits: at most the free capacity was taken from the device, and
        // only this task writes the pipe.
        try_write_all(&self.tx, &buf[..n]);
        n
    }

    /// Port side: bytes received from the host. What does not fit is
    /// dropped and counted; never waits. Returns the bytes kept.
    pub fn port_received(&self, bytes: &[u8]) -> usize {
        let mut kept = 0;
        while kept < bytes.len() {
            match self.rx.try_write(&bytes[kept..]) {
                Ok(n) => kept += n,
                Err(_) => break, // full
            }
        }
        let dropped = (bytes.len() - kept) as u32;
        if dropped > 0 {
            self.rx_dropped.fetch_add(dropped, Ordering::Relaxed);
        }
        kept
    }

    /// Port side: waits for bytes to send and takes up to `buf.len()`.
    pub async fn port_next_tx(&self, buf: &mut [u8]) -> usize {
        self.tx.read(buf).await
    }

    /// Port side: takes queued bytes to send without waiting (0 when none).
    pub fn port_try_tx(&self, buf: &mut [u8]) -> usize {
        self.tx.try_read(buf).unwrap_or(0)
    }

    /// Received bytes dropped because the receive pipe was full (a host
    /// sending faster than the control task reads), since boot.
    pub fn rx_dropped_bytes(&self) -> u32 {
        self.rx_dropped.load(Ordering::Relaxed)
    }

    /// Bytes waiting for the control task.
    pub fn rx_len(&self) -> usize {
        self.rx.len()
    }

    /// Bytes waiting for the port.
    pub fn tx_len(&self) -> usize {
        self.tx.len()
    }
}

/// Writes as much of `bytes` as fits into `pipe` without waiting; returns
/// how much. One `Pipe::try_write` is not enough: it stops at the end of
/// the pipe's ring buffer, so a chunk that straddles the wrap point would
/// lose its tail (a telemetry frame in four was cut this way before).
fn try_write_all<const N: usize>(pipe: &Pipe<CriticalSectionRawMutex, N>, bytes: &[u8]) -> usize {
    let mut n = 0;
    while n < bytes.len() {
        match pipe.try_write(&bytes[n..]) {
            Ok(k) => n += k,
            Err(_) => break, // full
        }
    }
    n
}

/// Port → pipe, forever: reads the port (waiting for bytes) and hands them
/// to [`LinkPipes::port_received`]. A port read error (framing, overrun) is
/// skipped: the protocol's CRC catches the damaged frame.
pub async fn pump_rx<R: embedded_io_async::Read>(port: &mut R, pipes: &LinkPipes) -> ! {
    let mut buf = [0u8; 64];
    loop {
        if let Ok(n) = port.read(&mut buf).await {
            pipes.port_received(&buf[..n]);
        }
    }
}

/// Pipe → port, forever: waits for queued bytes and writes them all. A
/// UART always drains at its baud rate; a write error drops the chunk.
pub async fn pump_tx<W: embedded_io_async::Write>(port: &mut W, pipes: &LinkPipes) -> ! {
    let mut buf = [0u8; 64];
    loop {
        let n = pipes.port_next_tx(&mut buf).await;
        let _ = port.write_all(&buf[..n]).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type SmallPipe = Pipe<CriticalSectionRawMutex, 8>;

    /// A pipe whose ring has 2 bytes before its wrap point and 8 free.
    fn pipe_near_wrap() -> SmallPipe {
        let pipe = SmallPipe::new();
        let mut sink = [0u8; 8];
        assert_eq!(pipe.try_write(&[9; 6]), Ok(6));
        assert_eq!(pipe.try_read(&mut sink), Ok(6));
        pipe
    }

    /// A chunk that straddles the ring buffer's wrap point arrives whole
    /// and in order; one `try_write` stops at the wrap (the control).
    #[test]
    fn writes_across_the_ring_wrap_are_whole() {
        let bytes = [10, 11, 12, 13, 14];
        assert_eq!(pipe_near_wrap().try_write(&bytes), Ok(2));

        let pipe = pipe_near_wrap();
        assert_eq!(try_write_all(&pipe, &bytes), 5);
        let mut got = [0u8; 8];
        let mut n = 0;
        while let Ok(k) = pipe.try_read(&mut got[n..]) {
            n += k;
        }
        assert_eq!(&got[..n], &bytes);
        // What does not fit is reported, not written.
        assert_eq!(try_write_all(&pipe, &[0; 12]), 8);
    }
}
