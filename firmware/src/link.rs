//! The host link's transport. The control task (robot-app) owns the
//! protocol handler (`wmr_device::Device`); this module only moves bytes
//! between the port and the two bounded pipes of [`PIPES`], and the control
//! task never waits on them. When the host stops reading or unplugs, the
//! send pipe fills and the device drops (and counts) telemetry.
//!
//! * STM32F411CE: USB CDC-ACM (embassy-usb, OTG_FS on PA11/PA12, VBUS
//!   detection off: PA9 is the left PWM output).
//!   - Receive: the OUT endpoint is read only when the receive pipe has
//!     room for a whole packet (`LinkPipes::port_wait_rx_room`); until
//!     then the endpoint NAKs and the host retries: a flooding host is held
//!     off, nothing is dropped.
//!   - Send: only while the host holds DTR (a program has the port open;
//!     Linux and macOS raise it on open). While DTR is low what the device
//!     queues is discarded (counted), and the backlog is discarded again
//!     when DTR rises, so a host that opens the port reads fresh replies.
//!     A packet write that does not complete within
//!     `usb::USB_WRITE_TIMEOUT_MS` (a host that is gone) is dropped, so a
//!     stalled host never holds the link task either.
//!   - Unplug vs suspend: without VBUS sensing (PA9 is a PWM output) an
//!     unplugged cable looks like a USB suspend (the bus goes idle). Either
//!     way the device stops sending once the write times out, and the
//!     robot side treats it as link silence (`link_timeout_ms`: a moving
//!     robot brakes to a stop). On re-plug the host re-enumerates the
//!     device and the link resumes; no state is lost.
//! * STM32F446RE: USART2 on PA2 (TX) / PA3 (RX), the ST-LINK's virtual COM
//!   port, 115 200 baud 8N1 (11.5 kB/s: about 60 telemetry frames per second
//!   with every group; choose the rate with `wmr params set telemetry_rate_hz`).
//!   No flow control: a flooding host overflows the receive pipe (bytes
//!   dropped and counted, frames then fail their CRC and are counted by the
//!   device). The receive interrupt counts the hardware's overrun, framing,
//!   noise and parity flags and the bytes the driver's ring drops
//!   (embassy-stm32 0.6 drops them silently) before embassy's handler runs;
//!   both reach `wmr status` (`board: port rx dropped / errors`).

use robot_app::LinkPipes;

/// The link's byte pipes between the port's task and the control task
/// (`robot_app::link`: bounded, the control task never waits on them).
pub static PIPES: LinkPipes = LinkPipes::new();

#[cfg(feature = "stm32f411ce")]
pub use usb::{start, LinkPeripherals};

#[cfg(feature = "stm32f411ce")]
mod usb {
    use super::PIPES;
    use defmt::unwrap;
    use embassy_executor::Spawner;
    use embassy_stm32::peripherals::{PA11, PA12, USB_OTG_FS};
    use embassy_stm32::usb::Driver;
    use embassy_stm32::{bind_interrupts, Peri};
    use embassy_time::{with_timeout, Duration};
    use embassy_usb::class::cdc_acm::{CdcAcmClass, State};
    use embassy_usb::{Builder, UsbDevice};
    use static_cell::StaticCell;

    /// A USB packet write that takes longer than this is dropped \[ms\].
    pub const USB_WRITE_TIMEOUT_MS: u64 = 20;
    const MAX_PACKET: u16 = 64;
    /// The CDC data IN endpoint's number: embassy-usb allocates the
    /// notification endpoint first (0x81), then the data OUT (0x01) and IN
    /// (0x82) endpoints (the enumeration in stm32-emu/run.sh (g) prints and
    /// checks the addresses).
    const DATA_IN_EP: usize = 2;

    /// Disables the data IN endpoint if a packet armed before a bus reset
    /// (unplug/replug, host re-enumeration) still holds it enabled.
    ///
    /// The OTG core keeps DIEPCTLx.EPENA across a USB reset (only USBAEP
    /// is cleared, RM0383 §22.16.4), and embassy-usb-synopsys-otg 0.3.3
    /// neither disables IN endpoints on reset nor on re-enable, while its
    /// `write` waits for EPENA to clear: every later packet timed out
    /// (`USB_WRITE_TIMEOUT_MS`) and was dropped, so after a replug during
    /// telemetry the board never sent again until a reset (found by
    /// stm32-emu's unplug check; NuttX saw the same on F4/F7/H7 hardware,
    /// apache/nuttx#4505). The endpoint disable sequence of RM0383
    /// §22.17.7: SNAK and EPDIS, then EPDISD, cleared. Called only from the
    /// send task, the endpoint's one writer, right after (re)configuration,
    /// when none of its packets can be in flight. Returns whether it had to.
    fn release_stale_in_endpoint() -> bool {
        const OTG_FS: usize = 0x5000_0000;
        const EPENA: u32 = 1 << 31;
        const EPDIS: u32 = 1 << 30;
        const SNAK: u32 = 1 << 27;
        const EPDISD: u32 = 1 << 1;
        let diepctl = (OTG_FS + 0x900 + 0x20 * DATA_IN_EP) as *mut u32;
        let diepint = (OTG_FS + 0x908 + 0x20 * DATA_IN_EP) as *mut u32;
        // SAFETY: OTG_FS's DIEPCTL2/DIEPINT2 (RM0383 §22.16.4), clocked
        // while the USB device runs; the driver touches this endpoint only
        // from `write` (this task) and from endpoint_set_enabled, which has
        // just run.
        unsafe {
            let c = core::ptr::read_volatile(diepctl);
            if c & EPENA == 0 {
                return false;
            }
            core::ptr::write_volatile(diepctl, c | SNAK | EPDIS);
            // The core answers within a few PHY clocks; bounded.
            for _ in 0..100_000 {
                if core::ptr::read_volatile(diepint) & EPDISD != 0 {
                    break;
                }
            }
            core::ptr::write_volatile(diepint, EPDISD);
        }
        true
    }

    bind_interrupts!(struct Irqs {
        OTG_FS => embassy_stm32::usb::InterruptHandler<USB_OTG_FS>;
    });

    /// The peripherals of the link.
    pub struct LinkPeripherals {
        /// OTG_FS.
        pub otg: Peri<'static, USB_OTG_FS>,
        /// D+.
        pub dp: Peri<'static, PA12>,
        /// D−.
        pub dm: Peri<'static, PA11>,
    }

    type UsbDriver = Driver<'static, USB_OTG_FS>;

    /// Builds the CDC-ACM device and spawns its tasks.
    pub fn start(spawner: &Spawner, p: LinkPeripherals) {
        static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
        static CONFIG_DESC: StaticCell<[u8; 128]> = StaticCell::new();
        static BOS_DESC: StaticCell<[u8; 32]> = StaticCell::new();
        static CONTROL_BUF: StaticCell<[u8; 64]> = StaticCell::new();
        static CDC_STATE: StaticCell<State<'static>> = StaticCell::new();
        let mut config = embassy_stm32::usb::Config::default();
        // PA9, the OTG VBUS sense pin, is the left PWM output.
        config.vbus_detection = false;
        let driver = Driver::new_fs(p.otg, Irqs, p.dp, p.dm, EP_OUT.init([0; 256]), config);
        // pid.codes test VID/PID: replace with your own for a product.
        let mut ucfg = embassy_usb::Config::new(0x1209, 0x0001);

        ucfg.product = Some("trajectory-tracking robot");
        ucfg.max_packet_size_0 = 64;
        let mut builder = Builder::new(
            driver,
            ucfg,
            CONFIG_DESC.init([0; 128]),
            BOS_DESC.init([0; 32]),
            &mut [],
            CONTROL_BUF.init([0; 64]),
        );
        let class = CdcAcmClass::new(&mut builder, CDC_STATE.init(State::new()), MAX_PACKET);
        let usb = builder.build();
        spawner.spawn(unwrap!(usb_task(usb, class).ok()));
    }

    /// The USB device and the CDC-ACM class in one task (one task's
    /// overhead instead of two).
    #[embassy_executor::task]
    async fn usb_task(
        mut usb: UsbDevice<'static, UsbDriver>,
        class: CdcAcmClass<'static, UsbDriver>,
    ) {
        let (mut tx, mut rx, control) = class.split_with_control();
        let receive = async {
            let mut buf = [0u8; MAX_PACKET as usize];
            loop {
                rx.wait_connection().await;
                loop {
                    // Hold the host off (NAK) until a whole packet fits.
                    PIPES.port_wait_rx_room(MAX_PACKET as usize).await;
                    match rx.read_packet(&mut buf).await {
                        Ok(n) => {
                            PIPES.port_received(&buf[..n]);
                        }
                        Err(_) => break, // disconnected
                    }
                }
            }
        };
        // The port opened (DTR rises): drop what was queued for nobody.
        let dtr = async {
            loop {
                control.control_changed().await;
                if control.dtr() {
                    PIPES.discard_tx();
                }
            }
        };
        let send = async {
            // Short packets only (< 64 bytes): no zero-length packet needed.
            let mut buf = [0u8; MAX_PACKET as usize - 1];
            loop {
                tx.wait_connection().await;
                if release_stale_in_endpoint() {
                    defmt::warn!("USB: data IN endpoint still enabled after a bus reset: disabled");
                }
                loop {
                    let n = PIPES.port_next_tx(&mut buf).await;
                    if !control.dtr() {
                        // Nobody has the port open: not a backlog for later.
                        PIPES.count_tx_discarded(n);
                        continue;
                    }
                    match with_timeout(
                        Duration::from_millis(USB_WRITE_TIMEOUT_MS),
                        tx.write_packet(&buf[..n]),
                    )
                    .await
                    {
                        Ok(Ok(())) => {}
                        // Disconnected: wait for the host again.
                        Ok(Err(_)) => break,
                        // The host does not read: drop the packet.
                        Err(_) => {}
                    }
                }
            }
        };
        embassy_futures::join::join4(usb.run(), receive, send, dtr).await;
    }
}

#[cfg(feature = "stm32f446re")]
pub use uart::{start, LinkPeripherals};

#[cfg(feature = "stm32f446re")]
mod uart {
    use super::PIPES;
    use defmt::unwrap;
    use embassy_executor::Spawner;
    use embassy_stm32::peripherals::{PA2, PA3, USART2};
    use embassy_stm32::usart::{BufferedUart, BufferedUartRx, BufferedUartTx, Config};
    use embassy_stm32::{bind_interrupts, Peri};
    use static_cell::StaticCell;

    bind_interrupts!(struct Irqs {
        USART2 => RxAccounting, embassy_stm32::usart::BufferedInterruptHandler<USART2>;
    });

    /// The driver's receive ring \[bytes\].
    const RX_RING_BYTES: usize = 256;

    /// Runs before embassy's USART2 handler: counts the receiver's error
    /// flags (USART_SR PE, FE, NF, ORE; RM0390 §25.6.1) and whether the
    /// byte that raised RXNE still fits the driver's ring
    /// (`LinkPipes::port_hw_byte`). Reading SR alone clears nothing (the
    /// flags clear on SR then DR reads, which embassy's handler does next).
    struct RxAccounting;

    impl embassy_stm32::interrupt::typelevel::Handler<embassy_stm32::interrupt::typelevel::USART2>
        for RxAccounting
    {
        unsafe fn on_interrupt() {
            let sr = embassy_stm32::pac::USART2.sr().read();
            let errors = sr.pe() as u32 + sr.fe() as u32 + sr.ne() as u32 + sr.ore() as u32;
            PIPES.count_port_errors(errors);
            if sr.rxne() {
                PIPES.port_hw_byte(RX_RING_BYTES as u32);
            }
        }
    }

    /// The peripherals of the link.
    pub struct LinkPeripherals {
        /// USART2.
        pub usart: Peri<'static, USART2>,
        /// TX (to the ST-LINK's RX).
        pub tx: Peri<'static, PA2>,
        /// RX.
        pub rx: Peri<'static, PA3>,
    }

    /// Opens USART2 at 115 200 baud and spawns its tasks.
    pub fn start(spawner: &Spawner, p: LinkPeripherals) {
        static TX_BUF: StaticCell<[u8; 256]> = StaticCell::new();
        static RX_BUF: StaticCell<[u8; RX_RING_BYTES]> = StaticCell::new();
        let mut cfg = Config::default();
        cfg.baudrate = 115_200;
        let uart = unwrap!(BufferedUart::new(
            p.usart,
            p.rx,
            p.tx,
            TX_BUF.init([0; 256]),
            RX_BUF.init([0; RX_RING_BYTES]),
            Irqs,
            cfg
        )
        .ok());
        let (tx, rx) = uart.split();
        spawner.spawn(unwrap!(rx_task(rx).ok()));
        spawner.spawn(unwrap!(tx_task(tx).ok()));
    }

    /// Takes the ring's bytes in place and reports them taken before the
    /// ring frees them (exact ring-drop counting, `robot_app::pump_rx_ring`).
    #[embassy_executor::task]
    async fn rx_task(mut rx: BufferedUartRx<'static>) {
        robot_app::pump_rx_ring(&mut rx, &PIPES).await
    }

    /// A UART always drains (no host handshake), at the baud rate.
    #[embassy_executor::task]
    async fn tx_task(mut tx: BufferedUartTx<'static>) {
        robot_app::pump_tx(&mut tx, &PIPES).await
    }
}

/// Starts the link task when the board has its peripherals, and logs the
/// protocol version; logs why not otherwise (no USB clock on the HSI).
pub fn start_if_present(spawner: &embassy_executor::Spawner, p: Option<LinkPeripherals>) {
    match p {
        Some(p) => {
            start(spawner, p);
            defmt::info!(
                "host link: wmr-protocol {=u16}",
                wmr_protocol::PROTOCOL_VERSION
            );
        }
        None => defmt::error!("host link off (no USB clock on the HSI)"),
    }
}
