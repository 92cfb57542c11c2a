//! The host link's byte stream: UART0 of the MPS2 (a CMSDK APB UART at
//! 0x4000_4000) as embedded-io-async `Read` and `Write`.
//!
//! What QEMU 7.2 models (hw/char/cmsdk-apb-uart.c), and how it is used:
//! * one-byte RX and TX holding registers (`DATA`), no FIFO; `STATE` bit 0
//!   TX full, bit 1 RX full. QEMU offers the next host byte only when RX is
//!   enabled and the RX register is empty, so the host is back-pressured
//!   (the pty buffers) and no byte is lost as long as the guest reads;
//! * `INTSTATUS` bits are sticky until written back (write 1 to clear); the
//!   RX interrupt is raised when a byte arrives, the TX interrupt when the
//!   TX register goes from full to empty;
//! * `BAUDDIV` must be at least 16 (QEMU logs an error otherwise); the
//!   rate itself does not pace a pty, bytes move as fast as both ends take
//!   them;
//! * UART0's RX interrupt is IRQ 0 and its TX interrupt IRQ 1 on
//!   mps2-an385/an386.
//!
//! RX is interrupt driven: the handler moves the byte into a 256-byte
//! ring (an embassy-sync pipe) and wakes the reader. When the ring is full
//! it leaves the byte in `DATA` (QEMU then holds back the host) and the
//! reader re-runs the handler once it has made room. TX writes bytes while
//! the holding register takes them (a pty that is read takes them at
//! once) and waits for the TX interrupt only when it stays full (a host that
//! stopped reading).

use core::future::poll_fn;
use core::ptr::{read_volatile, write_volatile};
use core::sync::atomic::{AtomicBool, Ordering};
use core::task::Poll;

use cortex_m::peripheral::NVIC;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use embassy_sync::waitqueue::AtomicWaker;

const UART0: usize = 0x4000_4000;
const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const INTSTATUS: usize = 0x0C;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_TX_INTEN: u32 = 1 << 2;
const CTRL_RX_INTEN: u32 = 1 << 3;
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;

/// UART0's RX interrupt number on mps2-an385/an386 (TX is one more).
pub const UART0_RX_IRQ: i16 = 0;
/// UART0's TX interrupt number.
pub const UART0_TX_IRQ: i16 = 1;

/// The link's nominal rate \[baud\] (the F446's ST-LINK UART's; a pty is
/// not paced by it).
pub const BAUD: u32 = 115_200;

static RX_RING: Pipe<CriticalSectionRawMutex, 256> = Pipe::new();
/// The RX handler left a byte in `DATA` because the ring was full.
static RX_STALLED: AtomicBool = AtomicBool::new(false);
static TX_WAKER: AtomicWaker = AtomicWaker::new();

fn read(off: usize) -> u32 {
    // SAFETY: a register of UART0 in the mps2 memory map.
    unsafe { read_volatile((UART0 + off) as *const u32) }
}

fn write(off: usize, v: u32) {
    // SAFETY: as in `read`.
    unsafe { write_volatile((UART0 + off) as *mut u32, v) }
}

/// An interrupt line of this module as cortex-m's NVIC wants it.
#[derive(Clone, Copy)]
struct Irq(u16);

// SAFETY: the numbers are device interrupts of the mps2-an386.
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0
    }
}

/// UART0, enabled: TX and RX on, RX interrupt on, TX interrupt off until a
/// writer waits.
pub struct Uart0 {
    _private: (),
}

/// The receiving half.
pub struct Rx {
    _private: (),
}

/// The sending half.
pub struct Tx {
    _private: (),
}

impl Uart0 {
    /// Configures UART0 at [`BAUD`] (`BAUDDIV` = 25 MHz / 115 200 = 217,
    /// above QEMU's minimum of 16) and unmasks its interrupts. Call once.
    pub fn new(cpu_hz: u32) -> Self {
        write(CTRL, 0);
        write(BAUDDIV, (cpu_hz / BAUD).max(16));
        write(INTSTATUS, INT_TX | INT_RX);
        write(CTRL, CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INTEN);
        // SAFETY: the handlers (`on_rx`, `on_tx`) only touch this module's
        // statics and registers; unmasking cannot break a critical section.
        unsafe {
            NVIC::unmask(Irq(UART0_RX_IRQ as u16));
            NVIC::unmask(Irq(UART0_TX_IRQ as u16));
        }
        Self { _private: () }
    }

    /// The two halves, for the two pump tasks.
    pub fn split(self) -> (Rx, Tx) {
        (Rx { _private: () }, Tx { _private: () })
    }
}

/// UART0 RX interrupt: the received byte into the ring (or left in
/// `DATA` while the ring is full).
pub fn on_rx() {
    write(INTSTATUS, INT_RX);
    while read(STATE) & STATE_RX_FULL != 0 {
        if RX_RING.free_capacity() == 0 {
            RX_STALLED.store(true, Ordering::Release);
            return;
        }
        let b = read(DATA) as u8;
        // Room was checked and only this handler writes the ring.
        let _ = RX_RING.try_write(&[b]);
    }
}

/// UART0 TX interrupt: the holding register emptied; wake the writer.
pub fn on_tx() {
    write(INTSTATUS, INT_TX);
    critical_section::with(|_| write(CTRL, read(CTRL) & !CTRL_TX_INTEN));
    TX_WAKER.wake();
}

impl embedded_io_async::ErrorType for Rx {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::ErrorType for Tx {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::Read for Rx {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        let n = RX_RING.read(buf).await;
        if RX_STALLED.swap(false, Ordering::AcqRel) {
            // Room now: let the handler take the byte QEMU is holding.
            NVIC::pend(Irq(UART0_RX_IRQ as u16));
        }
        Ok(n)
    }
}

impl embedded_io_async::Write for Tx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        if buf.is_empty() {
            return Ok(0);
        }
        poll_fn(|cx| {
            if read(STATE) & STATE_TX_FULL == 0 {
                return Poll::Ready(());
            }
            TX_WAKER.register(cx.waker());
            critical_section::with(|_| write(CTRL, read(CTRL) | CTRL_TX_INTEN));
            // It may have emptied before the interrupt was enabled.
            if read(STATE) & STATE_TX_FULL == 0 {
                Poll::Ready(())
            } else {
                Poll::Pending
            }
        })
        .await;
        let mut n = 0;
        while n < buf.len() && read(STATE) & STATE_TX_FULL == 0 {
            write(DATA, buf[n] as u32);
            n += 1;
        }
        Ok(n)
    }

    async fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}
