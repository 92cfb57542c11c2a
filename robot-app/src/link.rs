//! The host link's byte path: two bounded pipes between the port's task
//! and the control task.
//!
//! The control task owns the protocol handler ([`Device`]); the port side
//! (a UART task, a USB class, the emulated UART) only moves bytes. Neither
//! side waits on the other in the control task: [`LinkPipes::receive`] and
//! [`LinkPipes::transmit`] move at most what fits, so a silent host, a
//! flooding host or a host that stops reading never delays a tick. When the
//! host floods, what happens depends on the port:
//! * a port that can hold the host off (USB: an OUT endpoint that is not
//!   read NAKs) waits for room ([`LinkPipes::port_wait_rx_room`]) before it
//!   takes the next packet, so nothing is lost;
//! * a port that cannot (a UART without flow control) hands every byte to
//!   [`LinkPipes::port_received`], which drops and counts the excess
//!   ([`LinkPipes::rx_dropped_bytes`]); bytes the UART driver's own ring
//!   lost, and the receiver's hardware errors (overrun, framing, noise,
//!   parity), are counted too ([`LinkPipes::port_hw_byte`],
//!   [`LinkPipes::count_port_errors`]). The frames that lost bytes then
//!   fail their CRC and the device counts them.
//!
//! When the host stops reading, the send pipe fills and the device drops
//! (and counts) telemetry; when nobody has the port open (USB CDC-ACM with
//! DTR low) the port discards what the device sends
//! ([`LinkPipes::discard_tx`]), so a host that opens the port reads fresh
//! replies, not a backlog. The control task copies the port's counters into
//! the status the host reads (`wmr status`: `board`).

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use embassy_sync::signal::Signal;
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
    rx_errors: AtomicU32,
    tx_discarded: AtomicU32,
    /// Signalled when the control task took bytes from the receive pipe.
    rx_room: Signal<CriticalSectionRawMutex, ()>,
    /// Bytes the port's hardware received into its driver's ring.
    hw_bytes: AtomicU32,
    /// Bytes the port task took from that ring.
    taken_bytes: AtomicU32,
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
            rx_errors: AtomicU32::new(0),
            tx_discarded: AtomicU32::new(0),
            rx_room: Signal::new(),
            hw_bytes: AtomicU32::new(0),
            taken_bytes: AtomicU32::new(0),
        }
    }

    /// Control task, before the tick: received bytes into the device (at
    /// most what it accepts and [`wmr_device::RX_BYTES_PER_TICK`]). Returns
    /// the bytes moved.
    pub fn receive<const H: usize>(&self, dev: &mut Device<H>) -> usize {
        let mut buf = [0u8; wmr_device::RX_BYTES_PER_TICK];
        let room = dev.rx_free().min(buf.len());
        let n = self.read_rx(&mut buf[..room]);
        dev.push_rx(&buf[..n])
    }

    /// Control task: takes up to `buf.len()` received bytes (what
    /// [`receive`](Self::receive) does before the device); wakes a port
    /// waiting for room. Returns the bytes taken.
    pub fn read_rx(&self, buf: &mut [u8]) -> usize {
        if buf.is_empty() {
            return 0;
        }
        match self.rx.try_read(buf) {
            Ok(n) => {
                self.rx_room.signal(());
                n
            }
            Err(_) => 0, // empty
        }
    }

    /// Port side, for a port that can hold the host off: waits until the
    /// receive pipe has room for `n` bytes (at most [`PIPE_BYTES`]), so the
    /// next packet of up to `n` bytes fits whole. Meanwhile the port does
    /// not read its hardware (a USB OUT endpoint then NAKs the host).
    pub async fn port_wait_rx_room(&self, n: usize) {
        let n = n.min(PIPE_BYTES);
        while self.rx.free_capacity() < n {
            // Signalled after every read; a read between the check and
            // the wait leaves the signal set, so no wake-up is lost.
            self.rx_room.wait().await;
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
        self.queue_tx(&buf[..n]);
        n
    }

    /// Control task: queues bytes for the port without waiting (what
    /// [`transmit`](Self::transmit) does with the device's frames);
    /// returns how many fit.
    pub fn queue_tx(&self, bytes: &[u8]) -> usize {
        try_write_all(&self.tx, bytes)
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

    /// Received bytes dropped before the device: the receive pipe full (a
    /// host sending faster than the control task reads) or the port
    /// driver's ring full ([`port_hw_byte`](Self::port_hw_byte)), since boot.
    pub fn rx_dropped_bytes(&self) -> u32 {
        self.rx_dropped.load(Ordering::Relaxed)
    }

    /// Port side (its interrupt): the receiver's hardware flagged `n`
    /// errors (UART overrun, framing, noise, parity).
    pub fn count_port_errors(&self, n: u32) {
        if n > 0 {
            self.rx_errors.fetch_add(n, Ordering::Relaxed);
        }
    }

    /// Receive errors the port's hardware flagged, since boot.
    pub fn rx_port_errors(&self) -> u32 {
        self.rx_errors.load(Ordering::Relaxed)
    }

    /// Port side, in the receive interrupt before the driver stores the
    /// byte: one byte arrived for a driver ring of `ring_bytes`. When the
    /// bytes in the ring (arrived minus [taken](Self::port_taken)) already
    /// fill it, the driver drops this one: counted in
    /// [`rx_dropped_bytes`](Self::rx_dropped_bytes). Returns whether the
    /// byte fits. (embassy-stm32 0.6's buffered UART drops it silently.)
    pub fn port_hw_byte(&self, ring_bytes: u32) -> bool {
        let hw = self.hw_bytes.load(Ordering::Relaxed);
        let taken = self.taken_bytes.load(Ordering::Relaxed);
        if hw.wrapping_sub(taken) >= ring_bytes {
            self.rx_dropped.fetch_add(1, Ordering::Relaxed);
            false
        } else {
            self.hw_bytes.store(hw.wrapping_add(1), Ordering::Relaxed);
            true
        }
    }

    /// Port side (task): `n` bytes taken from the driver's ring, called
    /// before the ring frees them (so the interrupt never sees more room
    /// than there is: a miscount can only miss a drop, never invent one).
    pub fn port_taken(&self, n: usize) {
        self.taken_bytes.fetch_add(n as u32, Ordering::Relaxed);
    }

    /// Port side: discards every byte waiting to be sent (nobody has the
    /// port open: USB CDC-ACM with DTR low) and counts them. Returns how
    /// many.
    pub fn discard_tx(&self) -> usize {
        let mut sink = [0u8; 64];
        let mut n = 0;
        while let Ok(k) = self.tx.try_read(&mut sink) {
            n += k;
        }
        self.count_tx_discarded(n);
        n
    }

    /// Port side: `n` bytes taken for sending were discarded (no reader).
    pub fn count_tx_discarded(&self, n: usize) {
        if n > 0 {
            self.tx_discarded.fetch_add(n as u32, Ordering::Relaxed);
        }
    }

    /// Bytes discarded because nobody had the port open, since boot.
    pub fn tx_discarded_bytes(&self) -> u32 {
        self.tx_discarded.load(Ordering::Relaxed)
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
/// to [`LinkPipes::port_received`] (a port that cannot hold the host off:
/// the excess is dropped and counted). A port read error is counted
/// ([`LinkPipes::rx_port_errors`]) and skipped: the protocol's CRC catches
/// the damaged frame.
pub async fn pump_rx<R: embedded_io_async::Read>(port: &mut R, pipes: &LinkPipes) -> ! {
    let mut buf = [0u8; 64];
    loop {
        match port.read(&mut buf).await {
            Ok(n) => {
                pipes.port_received(&buf[..n]);
            }
            Err(_) => pipes.count_port_errors(1),
        }
    }
}

/// [`pump_rx`] for a port whose driver buffers in a ring and whose
/// interrupt calls [`LinkPipes::port_hw_byte`] (the STM32 buffered UART):
/// takes the ring's bytes in place and reports them taken
/// ([`LinkPipes::port_taken`]) before the ring frees them, so the ring's
/// own drops are counted exactly.
pub async fn pump_rx_ring<R: embedded_io_async::BufRead>(port: &mut R, pipes: &LinkPipes) -> ! {
    loop {
        let n = match port.fill_buf().await {
            Ok(bytes) => {
                pipes.port_received(bytes);
                bytes.len()
            }
            Err(_) => {
                pipes.count_port_errors(1);
                continue;
            }
        };
        pipes.port_taken(n);
        port.consume(n);
    }
}

/// Bytes [`pump_tx`] hands the port at once: at most the smallest driver
/// ring it feeds (embassy-stm32's `BufferedUartTx` refuses a write longer
/// than its ring; the firmware's is 256 B).
pub const TX_CHUNK_BYTES: usize = 64;

/// Pipe → port, forever: waits for queued bytes, writes them and waits
/// until the port has sent them (`flush`) before taking the next chunk. A
/// UART always drains at its baud rate; a write error drops the chunk.
///
/// The flush is not optional: embassy-stm32 0.6's `BufferedUartTx::write`
/// writes all of a chunk or nothing, and when its ring has less room than
/// the chunk it returns `Pending` *without registering a waker*, so a
/// write into a partly full ring is never polled again and the link goes
/// silent for good (found by stm32-emu on the F446 image at 100 Hz
/// telemetry, D50). After a flush the ring is empty, so every write fits
/// at once, and the flush itself waits on the driver's waker. What the
/// line cannot carry stays in the pipe, and the control task drops and
/// counts what no longer fits there (`tx_discarded`).
pub async fn pump_tx<W: embedded_io_async::Write>(port: &mut W, pipes: &LinkPipes) -> ! {
    let mut buf = [0u8; TX_CHUNK_BYTES];
    loop {
        let n = pipes.port_next_tx(&mut buf).await;
        let _ = port.write_all(&buf[..n]).await;
        let _ = port.flush().await;
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
