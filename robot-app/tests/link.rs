//! The link pipes' port side: hold-off instead of drops for a port that can
//! NAK, exact counting of a driver ring's drops, the backlog discarded while
//! nobody has the port open, and the reset-cause decoding; and the port's
//! counters reaching the host's status through the control task.

use core::future::Future;
use core::pin::pin;
use core::task::{Context, RawWaker, RawWakerVTable, Waker};

use robot_app::reset::{from_stm32f4_csr, stm32f4_csr::*};
use robot_app::LinkPipes;
use wmr_protocol::ResetCause;

fn noop_waker() -> Waker {
    fn clone(_: *const ()) -> RawWaker {
        RawWaker::new(core::ptr::null(), &VTABLE)
    }
    fn noop(_: *const ()) {}
    static VTABLE: RawWakerVTable = RawWakerVTable::new(clone, noop, noop, noop);
    // SAFETY: the vtable's functions do nothing.
    unsafe { Waker::from_raw(RawWaker::new(core::ptr::null(), &VTABLE)) }
}

fn ready<F: Future>(f: core::pin::Pin<&mut F>) -> bool {
    let w = noop_waker();
    f.poll(&mut Context::from_waker(&w)).is_ready()
}

/// A full pipe keeps the port waiting (it does not read its endpoint: the
/// host is NAKed); the control task's read makes room and releases it.
#[test]
fn a_port_waits_for_room_instead_of_dropping() {
    let pipes = LinkPipes::new();
    assert_eq!(pipes.port_received(&[7; 512]), 512);
    let mut wait = pin!(pipes.port_wait_rx_room(64));
    assert!(!ready(wait.as_mut()), "full pipe: the port must wait");
    let mut buf = [0u8; 32];
    assert_eq!(pipes.read_rx(&mut buf), 32);
    assert!(
        !ready(wait.as_mut()),
        "32 B free: a 64 B packet does not fit yet"
    );
    assert_eq!(pipes.read_rx(&mut buf), 32);
    assert!(ready(wait.as_mut()), "64 B free: the packet fits");
    assert_eq!(pipes.rx_dropped_bytes(), 0);
}

/// A host flooding 20 kB in 64 B packets, 3 per tick, while the control
/// task reads 128 B per tick: with the hold-off every byte arrives, in order; handing
/// the same packets over without it (the control) drops bytes.
#[test]
fn a_flood_with_hold_off_loses_nothing() {
    let bytes: Vec<u8> = (0..20_000u32).map(|i| (i % 251) as u8).collect();
    for hold_off in [true, false] {
        let pipes = LinkPipes::new();
        let mut got = Vec::new();
        let mut packets = bytes.chunks(64).peekable();
        let mut tick_buf = [0u8; 128];
        let mut ticks = 0;
        while packets.peek().is_some() || pipes.rx_len() > 0 {
            // The host offers 3 packets (192 B) per 1 ms tick, more than the
            // 128 B the control task takes: the port takes what it may.
            for _ in 0..3 {
                let Some(p) = packets.peek() else { break };
                if hold_off {
                    let mut w = pin!(pipes.port_wait_rx_room(p.len()));
                    if !ready(w.as_mut()) {
                        break; // NAKed: the host retries the packet later
                    }
                }
                pipes.port_received(p);
                packets.next();
            }
            let n = pipes.read_rx(&mut tick_buf);
            got.extend_from_slice(&tick_buf[..n]);
            ticks += 1;
            assert!(ticks < 10_000);
        }
        if hold_off {
            assert_eq!(pipes.rx_dropped_bytes(), 0);
            assert_eq!(got, bytes, "every byte, in order");
        } else {
            assert!(pipes.rx_dropped_bytes() > 0, "the control drops");
            assert_eq!(got.len() + pipes.rx_dropped_bytes() as usize, bytes.len());
        }
    }
}

/// A driver ring of 256 B: 300 bytes arriving while the port task takes
/// none lose exactly 44, counted; taken as they come, none.
#[test]
fn ring_drops_are_counted_exactly() {
    let pipes = LinkPipes::new();
    let stored = (0..300).filter(|_| pipes.port_hw_byte(256)).count();
    assert_eq!(stored, 256);
    assert_eq!(pipes.rx_dropped_bytes(), 44);
    // The task takes 100: 100 more fit, the 101st is dropped.
    pipes.port_taken(100);
    let stored = (0..101).filter(|_| pipes.port_hw_byte(256)).count();
    assert_eq!(stored, 100);
    assert_eq!(pipes.rx_dropped_bytes(), 45);

    let pipes = LinkPipes::new();
    for _ in 0..10_000 {
        assert!(pipes.port_hw_byte(256));
        pipes.port_taken(1);
    }
    assert_eq!(pipes.rx_dropped_bytes(), 0);
    pipes.count_port_errors(2);
    pipes.count_port_errors(0);
    assert_eq!(pipes.rx_port_errors(), 2);
}

/// What the device queued while nobody had the port open is discarded
/// (counted), so the first bytes a host reads are fresh.
#[test]
fn the_backlog_is_discarded_while_the_port_is_closed() {
    let pipes = LinkPipes::new();
    assert_eq!(pipes.queue_tx(&[0xAB; 300]), 300);
    assert_eq!(pipes.queue_tx(&[0xCD; 300]), 212, "the pipe holds 512");
    assert_eq!(pipes.discard_tx(), 512);
    assert_eq!(pipes.tx_len(), 0);
    assert_eq!(pipes.tx_discarded_bytes(), 512);
    let mut buf = [0u8; 8];
    assert_eq!(pipes.port_try_tx(&mut buf), 0, "nothing stale left");
    // After the port opens, new bytes go through untouched.
    assert_eq!(pipes.queue_tx(&[1, 2, 3]), 3);
    assert_eq!(pipes.port_try_tx(&mut buf), 3);
    assert_eq!(&buf[..3], &[1, 2, 3]);
}

/// RM0383 §6.3.20: a watchdog reset also pulses NRST (PINRSTF), a power-on
/// sets BORRSTF and PINRSTF too: the specific flag wins.
#[test]
fn reset_cause_from_the_rcc_flags() {
    assert_eq!(
        from_stm32f4_csr(PORRSTF | BORRSTF | PINRSTF),
        ResetCause::PowerOn
    );
    assert_eq!(from_stm32f4_csr(BORRSTF | PINRSTF), ResetCause::BrownOut);
    assert_eq!(from_stm32f4_csr(PINRSTF), ResetCause::Pin);
    assert_eq!(
        from_stm32f4_csr(IWDGRSTF | PINRSTF),
        ResetCause::IndependentWatchdog
    );
    assert_eq!(
        from_stm32f4_csr(WWDGRSTF | PINRSTF),
        ResetCause::WindowWatchdog
    );
    assert_eq!(from_stm32f4_csr(SFTRSTF | PINRSTF), ResetCause::Software);
    assert_eq!(from_stm32f4_csr(LPWRRSTF | PINRSTF), ResetCause::LowPower);
    // The reset value's other bits (LSION, LSIRDY, RMVF) name no cause.
    assert_eq!(from_stm32f4_csr(0b11 | RMVF), ResetCause::Unknown);
}

/// The ring and waker of [`EmbassyLikeUartTx`], shared with the test's
/// "interrupt".
#[derive(Default)]
struct UartState {
    ring: std::collections::VecDeque<u8>,
    waker: Option<Waker>,
}

/// A model of embassy-stm32 0.6's `BufferedUartTx` (usart/buffered.rs):
/// a 256 B ring that the interrupt drains at the baud rate; `write` takes
/// all of a chunk or nothing and, when the ring lacks room, returns
/// `Pending` without registering a waker (the driver's behaviour); `flush`
/// registers the waker, which the interrupt wakes on transmission complete.
struct EmbassyLikeUartTx(std::rc::Rc<std::cell::RefCell<UartState>>);

const UART_RING_BYTES: usize = 256;

impl embedded_io_async::ErrorType for EmbassyLikeUartTx {
    type Error = core::convert::Infallible;
}

impl embedded_io_async::Write for EmbassyLikeUartTx {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        core::future::poll_fn(|_cx| {
            let mut st = self.0.borrow_mut();
            if UART_RING_BYTES - st.ring.len() < buf.len() {
                return core::task::Poll::Pending; // no waker registered
            }
            st.ring.extend(buf);
            core::task::Poll::Ready(Ok(buf.len()))
        })
        .await
    }

    async fn flush(&mut self) -> Result<(), Self::Error> {
        core::future::poll_fn(|cx| {
            let mut st = self.0.borrow_mut();
            if st.ring.is_empty() {
                core::task::Poll::Ready(Ok(()))
            } else {
                st.waker = Some(cx.waker().clone());
                core::task::Poll::Pending
            }
        })
        .await
    }
}

/// A waker that sets a flag: the test polls the pump only when woken, as
/// an executor does.
fn flag_waker(flag: &std::sync::Arc<std::sync::atomic::AtomicBool>) -> Waker {
    struct Flag(std::sync::Arc<std::sync::atomic::AtomicBool>);
    impl std::task::Wake for Flag {
        fn wake(self: std::sync::Arc<Self>) {
            self.0.store(true, std::sync::atomic::Ordering::SeqCst);
        }
    }
    Waker::from(std::sync::Arc::new(Flag(flag.clone())))
}

/// Bytes queued, bytes sent on the line and bytes left in the pipe after
/// 1 s of telemetry faster than the line (160 B every 10 ms against 11 B/ms
/// at 115 200 baud: wmr's default 100 Hz on a UART) and 1 s to drain, with
/// `pump` between the pipe and the embassy-like driver.
fn uart_flood<F: Future>(
    pump: impl FnOnce(EmbassyLikeUartTx, &'static LinkPipes) -> F,
) -> (usize, usize, usize) {
    let pipes: &'static LinkPipes = Box::leak(Box::new(LinkPipes::new()));
    let state = std::rc::Rc::new(std::cell::RefCell::new(UartState::default()));
    let mut pump = pin!(pump(EmbassyLikeUartTx(state.clone()), pipes));
    let woken = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let waker = flag_waker(&woken);
    let mut cx = Context::from_waker(&waker);
    let (mut queued, mut sent) = (0usize, 0usize);
    for ms in 0..2_000u32 {
        if ms < 1_000 && ms % 10 == 0 {
            queued += pipes.queue_tx(&[0xA5; 160]);
        }
        // The interrupt: 11 bytes per ms leave the ring; transmission
        // complete wakes the flush.
        let wake = {
            let mut st = state.borrow_mut();
            for _ in 0..11 {
                sent += st.ring.pop_front().is_some() as usize;
            }
            if st.ring.is_empty() {
                st.waker.take()
            } else {
                None
            }
        };
        if let Some(w) = wake {
            w.wake();
        }
        if woken.swap(false, std::sync::atomic::Ordering::SeqCst) {
            let _ = pump.as_mut().poll(&mut cx);
        }
    }
    (queued, sent, pipes.tx_len())
}

/// The UART pump keeps sending for as long as bytes are queued, and the
/// line carries everything the pipe accepted (the excess is refused by the
/// pipe and counted by the control task, never a silent link). The
/// control: a pump that writes without flushing stalls for good on the
/// driver's waker-less `Pending` (the bug stm32-emu found on the F446 image).
#[test]
fn the_uart_pump_never_stalls_on_a_full_driver_ring() {
    let (queued, sent, left) =
        uart_flood(|mut port, pipes| async move { robot_app::pump_tx(&mut port, pipes).await });
    assert!(queued > 4_000, "the pipe took {queued} B");
    assert_eq!(left, 0, "bytes left in the pipe");
    assert_eq!(sent, queued, "every byte the pipe took reaches the line");

    let (queued, sent, left) = uart_flood(|mut port, pipes| async move {
        let mut chunk = [0u8; robot_app::TX_CHUNK_BYTES];
        loop {
            let n = pipes.port_next_tx(&mut chunk).await;
            let _ = embedded_io_async::Write::write_all(&mut port, &chunk[..n]).await;
        }
    });
    assert!(
        sent < queued / 2 && left > 0,
        "the control must stall: {sent} of {queued} B sent, {left} left"
    );
}
