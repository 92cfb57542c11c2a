//! Address decoding: which model a bus access reaches, the clock gates,
//! the names of unmodelled registers, the RCC peripheral resets, and
//! Unicorn's MMIO callbacks.

use super::*;

impl Board {
    /// Name of the peripheral at `addr`, for unmodelled accesses.
    pub(super) fn periph_name(addr: u32) -> &'static str {
        const MAP: &[(u32, u32, &str)] = &[
            (0x4000_0000, 0x400, "TIM2"),
            (0x4000_1000, 0x400, "TIM6"),
            (0x4000_1400, 0x400, "TIM7"),
            (0x4000_2800, 0x400, "RTC"),
            (0x4000_2C00, 0x400, "WWDG"),
            (0x4000_3800, 0x400, "SPI2"),
            (0x4000_3C00, 0x400, "SPI3"),
            (0x4000_4800, 0x400, "USART3"),
            (0x4000_4C00, 0x400, "UART4"),
            (0x4000_5400, 0x400, "I2C1"),
            (0x4000_5800, 0x400, "I2C2"),
            (0x4001_1000, 0x400, "USART1"),
            (0x4001_1400, 0x400, "USART6"),
            (0x4001_2000, 0x400, "ADC1"),
            (0x4001_3000, 0x400, "SPI1"),
            (0x4001_3800, 0x400, "SYSCFG"),
            (0x4001_3C00, 0x400, "EXTI"),
            (0x4002_3000, 0x400, "CRC"),
            (0x4002_6000, 0x400, "DMA1"),
            (0x4002_6400, 0x400, "DMA2"),
            (0x5000_0000, 0x4_0000, "USB_OTG_FS"),
            (0xE000_0000, 0x1000, "ITM"),
            (0xE000_2000, 0x1000, "FPB"),
            (0xE004_0000, 0x1000, "TPIU"),
        ];
        MAP.iter()
            .find(|m| addr >= m.0 && addr < m.0 + m.1)
            .map_or("unknown peripheral", |m| m.2)
    }

    /// A clock-enable check: an access to a peripheral whose RCC clock is
    /// off reads 0 and ignores writes on the chip: a firmware bug.
    pub(super) fn clock_on(&self, name: &str, enr: u32, bit: u32) -> Result<(), String> {
        if self.rcc.enabled(enr, bit) {
            Ok(())
        } else {
            Err(format!(
                "{name} accessed with its clock off (RCC+0x{enr:02X} bit {bit})"
            ))
        }
    }

    /// A word read; `Err` names the register.
    pub(super) fn read_word(&mut self, addr: u32) -> Result<u32, String> {
        let now = self.now_ps();
        let off = addr & 0x3FF;
        match addr & !0x3FF {
            0x4002_3800 => self.rcc.read(off),
            0x4002_3C00 => self.flash.read(off, now),
            STORE_BASE..=0x0807_FC00 => self.flash.read_array(addr),
            0x4000_7000 => {
                self.clock_on("PWR", 0x40, 28)?;
                self.pwr.read(off)
            }
            0x4002_0000..=0x4002_1C00 => {
                let i = ((addr - 0x4002_0000) / 0x400) as usize;
                self.clock_on("GPIO", 0x30, i as u32)?;
                if i == 1 {
                    self.sda_line();
                }
                self.gpio[i].read(off)
            }
            0x4000_5400 => {
                self.clock_on("I2C1", 0x40, 21)?;
                self.stop_req = true;
                self.i2c1.read(off, now)
            }
            0x4002_6000 => {
                self.clock_on("DMA1", 0x30, 21)?;
                self.stop_req = true;
                self.dma1.read(off)
            }
            0x4001_0000 => {
                self.clock_on("TIM1", 0x44, 0)?;
                self.tim1.read(off, now, 0)
            }
            0x4000_0400 | 0x4000_0800 => {
                let right = addr & !0x3FF == 0x4000_0400;
                self.clock_on(
                    if right { "TIM3" } else { "TIM4" },
                    0x40,
                    if right { 1 } else { 2 },
                )?;
                let pos = self.encoder_pos()?;
                if right && off == 0x24 && self.fault_on_encoder_read {
                    self.fault_on_encoder_read = false;
                    self.scb.cfsr |= 1 << 10; // IMPRECISERR
                    if self.scb.shcsr & (1 << 17) != 0 {
                        self.nvic.set_pending(exc::BUS_FAULT);
                    } else {
                        self.scb.hfsr |= 1 << 30; // FORCED
                        self.nvic.set_pending(exc::HARD_FAULT);
                    }
                    self.fault_at = Some((now, self.cycles));
                    self.event(
                        "fault injected: bus error on TIM3.CNT read (imprecise BusFault)".into(),
                    );
                    self.stop_req = true;
                }
                if right {
                    self.tim3.read(off, now, pos[0])
                } else {
                    self.tim4.read(off, now, pos[1])
                }
            }
            0x4000_0C00 => {
                self.clock_on("TIM5", 0x40, 3)?;
                self.tim5.read(off, now, 0)
            }
            0x4000_3000 => self.iwdg.read(off),
            0x4000_4400 => {
                self.clock_on("USART2", 0x40, 17)?;
                self.usart2.read(off, now)
            }
            0x5000_0000..=0x5003_FC00 if self.usb_host.is_some() => {
                self.clock_on("USB_OTG_FS", 0x34, 7)?;
                let v = self.usb.read(addr - 0x5000_0000);
                // A pop of the RX FIFO or a cleared flag lowers the line.
                self.update_lines();
                v
            }
            _ => self.read_ppb(addr),
        }
    }

    pub(super) fn read_ppb(&mut self, addr: u32) -> Result<u32, String> {
        match addr {
            0xE000_1000..=0xE000_1FFF => {
                let tr = self.scb.demcr & (1 << 24) != 0;
                self.dwt.read(addr - 0xE000_1000, self.cycles, tr)
            }
            0xE000_E010..=0xE000_E01F => self.systick.read(addr - 0xE000_E010, self.cycles),
            0xE000_E100..=0xE000_E4EF => self.nvic.read(addr - 0xE000_E000),
            0xE000_E000..=0xE000_EFFF => {
                let va = self.vectactive();
                self.scb.read(addr - 0xE000_E000, &self.nvic, va)
            }
            0xE004_2000..=0xE004_2FFF => self.dbgmcu.read(addr - 0xE004_2000),
            _ => Err(Self::unknown(addr)),
        }
    }

    /// The name of an address no model covers.
    pub(super) fn unknown(addr: u32) -> String {
        let p = Self::periph_name(addr);
        // The F411 decodes OTG_FS itself (src/periph/otg_fs.rs); on the
        // F446 the block is not modelled and named by its registers here.
        let off = addr & 0x3FF;
        let reg = match (p, off) {
            ("USB_OTG_FS", 0x000) => " GOTGCTL",
            ("USB_OTG_FS", 0x008) => " GAHBCFG",
            ("USB_OTG_FS", 0x00C) => " GUSBCFG",
            ("USB_OTG_FS", 0x010) => " GRSTCTL",
            ("USB_OTG_FS", 0x014) => " GINTSTS",
            ("USB_OTG_FS", 0x018) => " GINTMSK",
            ("USB_OTG_FS", 0x038) => " GCCFG",
            ("USB_OTG_FS", 0x03C) => " CID",
            ("I2C1" | "I2C2", 0x00) => " CR1",
            ("I2C1" | "I2C2", 0x04) => " CR2",
            ("I2C1" | "I2C2", 0x14) => " SR1",
            _ => "",
        };
        format!("{p} +0x{off:X}{reg}")
    }

    pub(super) fn vectactive(&self) -> u32 {
        (1..16 + self.nvic.n_irq)
            .filter(|&e| self.nvic.is_active(e))
            .last()
            .unwrap_or(0) as u32
    }

    /// A word write under the byte-lane `mask`.
    pub(super) fn write_word(&mut self, addr: u32, value: u32, mask: u32) -> Result<(), String> {
        let now = self.now_ps();
        let off = addr & 0x3FF;
        match addr & !0x3FF {
            0x4002_3800 => {
                // Peripheral resets through the RSTR registers.
                if matches!(off, 0x10 | 0x14 | 0x20 | 0x24) {
                    self.peripheral_resets(off, value & mask);
                }
                if self.rcc.write(off, value, mask)? {
                    self.clocks_changed()?;
                }
                Ok(())
            }
            0x4002_3C00 => {
                self.flash.write(off, value, mask, now)?;
                self.flash_stall();
                Ok(())
            }
            STORE_BASE..=0x0807_FC00 => {
                self.flash.write_array(addr, value, mask, now)?;
                self.flash_stall();
                Ok(())
            }
            0x4000_7000 => {
                self.clock_on("PWR", 0x40, 28)?;
                self.pwr.write(off, value, mask)
            }
            0x4002_0000..=0x4002_1C00 => {
                let i = ((addr - 0x4002_0000) / 0x400) as usize;
                self.clock_on("GPIO", 0x30, i as u32)?;
                self.sync_robot()?;
                let scl = self.scl_line();
                self.gpio[i].write(off, value, mask)?;
                if i == 1 {
                    self.gpio_b_written(scl);
                }
                self.sync_robot()
            }
            0x4000_5400 => {
                self.clock_on("I2C1", 0x40, 21)?;
                if off == 0 && value & mask & crate::periph::i2c::cr1::START != 0 {
                    self.i2c_start_check()?;
                }
                self.stop_req = true;
                self.i2c1.write(off, value, mask, now)
            }
            0x4002_6000 => {
                self.clock_on("DMA1", 0x30, 21)?;
                self.stop_req = true;
                self.dma1.write(off, value, mask)
            }
            0x4001_0000 => {
                self.clock_on("TIM1", 0x44, 0)?;
                self.sync_robot()?;
                self.tim1.write(off, value, mask, now, 0)?;
                self.sync_robot()
            }
            0x4000_0400 | 0x4000_0800 => {
                let right = addr & !0x3FF == 0x4000_0400;
                self.clock_on(
                    if right { "TIM3" } else { "TIM4" },
                    0x40,
                    if right { 1 } else { 2 },
                )?;
                let pos = self.encoder_pos()?;
                if right {
                    self.tim3.write(off, value, mask, now, pos[0])
                } else {
                    self.tim4.write(off, value, mask, now, pos[1])
                }
            }
            0x4000_0C00 => {
                self.clock_on("TIM5", 0x40, 3)?;
                self.tim5.write(off, value, mask, now, 0)
            }
            0x4000_3000 => {
                let was = self.iwdg.running;
                let feeds = self.iwdg.feeds;
                let timeout = self.iwdg.timeout_ps();
                self.iwdg.write(off, value & mask, now)?;
                if was && self.iwdg.timeout_ps() != timeout {
                    let t = self.iwdg.timeout_ps() as f64 * 1e-9;
                    self.event(format!("IWDG timeout after a feed now {t:.1} ms"));
                }
                if self.iwdg.feeds != feeds {
                    self.stats.feeds += 1;
                }
                if !was && self.iwdg.running {
                    self.wiring_check()?;
                    self.loop_started = true;
                    self.repaint_stack = true;
                    self.stop_req = true;
                    let t = self.iwdg.timeout_ps() as f64 * 1e-9;
                    self.event(format!("IWDG started (timeout after a feed {t:.1} ms)"));
                }
                Ok(())
            }
            0x4000_4400 => {
                self.clock_on("USART2", 0x40, 17)?;
                self.usart2.write(off, value, mask, now)
            }
            0x5000_0000..=0x5003_FC00 if self.usb_host.is_some() => {
                self.clock_on("USB_OTG_FS", 0x34, 7)?;
                self.usb.write(addr - 0x5000_0000, value, mask)
            }
            _ => self.write_ppb(addr, value, mask),
        }
    }

    pub(super) fn write_ppb(&mut self, addr: u32, value: u32, mask: u32) -> Result<(), String> {
        match addr {
            0xE000_1000..=0xE000_1FFF => {
                self.dwt.write(addr - 0xE000_1000, value, mask, self.cycles)
            }
            0xE000_E010..=0xE000_E01F => {
                self.systick
                    .write(addr - 0xE000_E010, value, mask, self.cycles)
            }
            0xE000_E100..=0xE000_E4EF | 0xE000_EF00 => {
                self.nvic.write(addr - 0xE000_E000, value, mask)
            }
            0xE000_E000..=0xE000_EFFF => {
                self.scb
                    .write(addr - 0xE000_E000, value, mask, &mut self.nvic)
            }
            0xE004_2000..=0xE004_2FFF => self.dbgmcu.write(addr - 0xE004_2000, value, mask),
            _ => Err(Self::unknown(addr)),
        }
    }

    /// RCC AHB1RSTR / APB1RSTR / APB2RSTR bits: the models go back to
    /// their reset state.
    pub(super) fn peripheral_resets(&mut self, off: u32, bits: u32) {
        let now = self.now_ps();
        let c = self.rcc.clocks().ok();
        let (apb1t, apb2t, p1) = c.map_or((16_000_000, 16_000_000, 16_000_000), |c| {
            (c.timclk_apb1_hz, c.timclk_apb2_hz, c.pclk1_hz)
        });
        let _ = now;
        match off {
            0x10 => {
                for i in 0..8 {
                    if bits & (1 << i) != 0 {
                        self.gpio[i] = Port::new("ABCDEFGH".as_bytes()[i] as char);
                    }
                }
                if bits & (1 << 21) != 0 {
                    self.dma1 = crate::periph::dma::Dma::default();
                }
            }
            0x20 => {
                if bits & (1 << 1) != 0 {
                    self.tim3 = Timer::new("TIM3", Kind::General, apb1t);
                }
                if bits & (1 << 2) != 0 {
                    self.tim4 = Timer::new("TIM4", Kind::General, apb1t);
                }
                if bits & (1 << 3) != 0 {
                    self.tim5 = Timer::new("TIM5", Kind::General, apb1t);
                }
                if bits & (1 << 17) != 0 {
                    let q = std::mem::take(&mut self.usart2.rx_queue);
                    self.usart2 = Usart::new("USART2", p1);
                    self.usart2.rx_queue = q;
                }
                if bits & (1 << 28) != 0 {
                    self.pwr = Pwr::default();
                }
                if bits & (1 << 21) != 0 {
                    let stats = self.i2c1.stats;
                    self.i2c1 = crate::periph::i2c::I2c::new(p1);
                    self.i2c1.stats = stats;
                }
            }
            0x24 if bits & 1 != 0 => self.tim1 = Timer::new("TIM1", Kind::Advanced, apb2t),
            0x14 if bits & (1 << 7) != 0 => self.usb = crate::periph::otg_fs::OtgFs::new(),
            _ => {}
        }
    }
}

fn lane(addr: u32, size: usize) -> (u32, u32, u32) {
    let shift = 8 * (addr & 3);
    let mask = match size {
        1 => 0xFF,
        2 => 0xFFFF,
        _ => 0xFFFF_FFFF,
    } << shift;
    (addr & !3, shift, mask)
}

pub(super) fn mmio_read(uc: &mut Unicorn<Board>, addr: u32, size: usize) -> u64 {
    let (word, shift, mask) = lane(addr, size);
    let r = uc.get_data_mut().read_word(word);
    match r {
        Ok(v) => ((v & mask) >> shift) as u64,
        Err(what) => {
            let pc = rd(uc, RegisterARM::PC);
            uc.get_data_mut().unmodelled_addr = Some(addr);
            bad(
                uc,
                format!("unmodelled read of {size} B at 0x{addr:08X}: {what} (PC 0x{pc:08X})"),
            );
            0
        }
    }
}

pub(super) fn mmio_write(uc: &mut Unicorn<Board>, addr: u32, size: usize, value: u32) {
    let (word, shift, mask) = lane(addr, size);
    let r = uc.get_data_mut().write_word(word, value << shift, mask);
    match r {
        Ok(()) => {
            let d = uc.get_data_mut();
            d.update_lines();
            if d.nvic.highest_pending().is_some() {
                d.stop_req = true;
            }
        }
        Err(what) => {
            let pc = rd(uc, RegisterARM::PC);
            uc.get_data_mut().unmodelled_addr = Some(addr);
            bad(
                uc,
                format!(
                    "unmodelled write of 0x{value:X} ({size} B) at 0x{addr:08X}: {what} (PC 0x{pc:08X})"
                ),
            );
        }
    }
}
