//! Framing: the bounded receive and send buffers, the COBS frame decoder
//! and the link counters. The bottom layer: it knows frames and bytes, not
//! what the requests mean.

use heapless::Deque;
use wmr_protocol::{encode, FrameDecoder, Reply, MAX_FRAME};

/// Receive buffer \[bytes\].
pub const RX_CAPACITY: usize = 256;
/// Send buffer \[bytes\].
pub const TX_CAPACITY: usize = 1024;
/// Received bytes decoded per tick at most (bounded work per tick; 128 kB/s
/// at 1 kHz, above a 921 600 baud UART).
pub const RX_BYTES_PER_TICK: usize = 128;

/// Link counters kept by the device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct LinkCounters {
    pub rx_frames: u32,
    pub rx_errors: u32,
    pub rx_overflow: u32,
    pub tx_dropped: u32,
    pub nacks: u32,
}

/// Bytes in, frames out: the buffers, the decoder and their counters.
pub(crate) struct Framing {
    pub decoder: FrameDecoder<MAX_FRAME>,
    rx: Deque<u8, RX_CAPACITY>,
    tx: Deque<u8, TX_CAPACITY>,
    pub counters: LinkCounters,
}

/// Adds one to a counter, saturating.
pub(crate) fn bump(c: &mut u32) {
    *c = c.saturating_add(1);
}

impl Framing {
    pub fn new() -> Self {
        Self {
            decoder: FrameDecoder::new(),
            rx: Deque::new(),
            tx: Deque::new(),
            counters: LinkCounters::default(),
        }
    }

    /// Queues received bytes; returns how many fit (the rest are dropped
    /// and counted in `rx_overflow`).
    pub fn push_rx(&mut self, bytes: &[u8]) -> usize {
        let mut n = 0;
        for &b in bytes {
            if self.rx.push_back(b).is_err() {
                break;
            }
            n += 1;
        }
        let dropped = (bytes.len() - n) as u32;
        self.counters.rx_overflow = self.counters.rx_overflow.saturating_add(dropped);
        n
    }

    pub fn rx_free(&self) -> usize {
        RX_CAPACITY - self.rx.len()
    }

    /// Moves at most [`RX_BYTES_PER_TICK`] received bytes into `chunk`;
    /// returns how many.
    pub fn take_rx(&mut self, chunk: &mut [u8; RX_BYTES_PER_TICK]) -> usize {
        let mut n = 0;
        while n < chunk.len() {
            match self.rx.pop_front() {
                Some(b) => {
                    chunk[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    /// Moves queued outgoing bytes into `out`; returns how many.
    pub fn pop_tx(&mut self, out: &mut [u8]) -> usize {
        let mut n = 0;
        while n < out.len() {
            match self.tx.pop_front() {
                Some(b) => {
                    out[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }

    pub fn tx_len(&self) -> usize {
        self.tx.len()
    }

    /// Free space of the send buffer \[bytes\].
    pub fn tx_free(&self) -> usize {
        TX_CAPACITY - self.tx.len()
    }

    /// Queues a frame; drops (and counts) it when the send buffer is full.
    pub fn send(&mut self, reply: &Reply) -> bool {
        let mut buf = [0u8; MAX_FRAME];
        let Ok(frame) = encode(reply, 0, &mut buf) else {
            bump(&mut self.counters.tx_dropped);
            return false;
        };
        if self.tx_free() < frame.len() {
            bump(&mut self.counters.tx_dropped);
            return false;
        }
        for &b in frame.iter() {
            let _ = self.tx.push_back(b);
        }
        true
    }
}
