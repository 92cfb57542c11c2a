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
