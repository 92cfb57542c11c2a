//! DMA1 (RM0383 §9 / RM0390 §9, the F4's dual-port DMA): LISR/HISR,
//! LIFCR/HIFCR and the eight streams' CR, NDTR, PAR, M0AR, M1AR, FCR with
//! their reset values (FCR 0x21). A stream moves one item per peripheral
//! request while EN is set: direct mode, byte items, peripheral-to-memory
//! or memory-to-peripheral, memory increment; NDTR counts down, TCIF at 0
//! (EN cleared by hardware), HTIF at half; an interrupt line per stream
//! from TCIE/HTIE/TEIE. The harness moves the bytes (it owns the memory):
//! [`Dma::request`] says what to move. FIFO mode, circular, double buffer,
//! memory-to-memory, peripheral flow control and bursts fail the run.

use super::{merge, Access};

/// One stream's registers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stream {
    /// SxCR.
    pub cr: u32,
    /// SxNDTR.
    pub ndtr: u32,
    /// SxPAR.
    pub par: u32,
    /// SxM0AR.
    pub m0ar: u32,
    /// SxM1AR.
    pub m1ar: u32,
    /// SxFCR.
    pub fcr: u32,
    /// Items moved since EN was set (the memory address offset).
    moved: u32,
}

impl Default for Stream {
    fn default() -> Self {
        Self {
            cr: 0,
            ndtr: 0,
            par: 0,
            m0ar: 0,
            m1ar: 0,
            fcr: 0x21,
            moved: 0,
        }
    }
}

/// SxCR bits.
pub mod cr {
    /// Stream enable.
    pub const EN: u32 = 1 << 0;
    /// Transfer error interrupt enable.
    pub const TEIE: u32 = 1 << 2;
    /// Half transfer interrupt enable.
    pub const HTIE: u32 = 1 << 3;
    /// Transfer complete interrupt enable.
    pub const TCIE: u32 = 1 << 4;
}

/// Stream flags (in LISR/HISR at the stream's offset).
const FEIF: u32 = 1 << 0;
const DMEIF: u32 = 1 << 2;
const TEIF: u32 = 1 << 3;
const HTIF: u32 = 1 << 4;
const TCIF: u32 = 1 << 5;

/// Bit offset of stream `s`'s flags in its ISR (0, 6, 16, 22).
fn flag_shift(s: usize) -> u32 {
    [0, 6, 16, 22][s % 4]
}

/// Direction of a stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dir {
    /// Peripheral to memory.
    PeriphToMem,
    /// Memory to peripheral.
    MemToPeriph,
}

/// One item to move: from or to memory at `mem_addr`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Item {
    /// The stream.
    pub stream: usize,
    /// Direction.
    pub dir: Dir,
    /// Memory address of this item.
    pub mem_addr: u32,
}

/// DMA1.
#[derive(Clone, Debug, Default)]
pub struct Dma {
    /// The streams.
    pub streams: [Stream; 8],
    /// LISR (streams 0-3) and HISR (4-7).
    isr: [u32; 2],
    /// Items moved since reset.
    pub items: u64,
}

impl Dma {
    /// Reads the register at `off`.
    pub fn read(&mut self, off: u32) -> Access<u32> {
        Ok(match off {
            0x00 => self.isr[0],
            0x04 => self.isr[1],
            0x08 | 0x0C => 0, // write-only
            0x10..=0xCC => {
                let s = &self.streams[((off - 0x10) / 0x18) as usize];
                match (off - 0x10) % 0x18 {
                    0x00 => s.cr,
                    0x04 => s.ndtr,
                    0x08 => s.par,
                    0x0C => s.m0ar,
                    0x10 => s.m1ar,
                    _ => s.fcr,
                }
            }
            _ => return Err(format!("DMA1+0x{off:02X}")),
        })
    }

    /// Writes the register at `off`.
    pub fn write(&mut self, off: u32, value: u32, mask: u32) -> Access<()> {
        match off {
            0x00 | 0x04 => return Err(format!("DMA1 ISR write (read-only) at +0x{off:02X}")),
            0x08 | 0x0C => {
                // Write 1 to clear.
                self.isr[((off - 0x08) / 4) as usize] &= !(value & mask);
            }
            0x10..=0xCC => {
                let i = ((off - 0x10) / 0x18) as usize;
                let isr_flags = self.flags(i);
                let s = &mut self.streams[i];
                match (off - 0x10) % 0x18 {
                    0x00 => {
                        let v = merge(s.cr, value, mask) & 0x0FEF_FFFF;
                        let enabling = v & cr::EN != 0 && s.cr & cr::EN == 0;
                        if enabling {
                            // RM0383 §9.3.17: the stream's flags must be
                            // clear before EN is set.
                            if isr_flags & (TCIF | HTIF | TEIF | DMEIF | FEIF) != 0 {
                                return Err(format!(
                                    "DMA1 stream {i} enabled with its ISR flags set (0x{isr_flags:02X}): RM0383 §9.3.17"
                                ));
                            }
                            Self::check_config(i, v, s)?;
                            s.moved = 0;
                        }
                        s.cr = v;
                    }
                    0x04 => {
                        if s.cr & cr::EN != 0 {
                            return Err(format!("DMA1 S{i}NDTR written while enabled"));
                        }
                        s.ndtr = merge(s.ndtr, value, mask) & 0xFFFF;
                    }
                    0x08 => s.par = merge(s.par, value, mask),
                    0x0C => s.m0ar = merge(s.m0ar, value, mask),
                    0x10 => s.m1ar = merge(s.m1ar, value, mask),
                    _ => s.fcr = (merge(s.fcr, value, mask) & 0xBF) | (s.fcr & 0x38),
                }
            }
            _ => return Err(format!("DMA1+0x{off:02X}")),
        }
        Ok(())
    }

    fn check_config(i: usize, v: u32, s: &Stream) -> Access<()> {
        let dir = (v >> 6) & 3;
        let bad = if v & (1 << 5) != 0 {
            Some("peripheral flow control (PFCTRL)")
        } else if dir > 1 {
            Some("memory-to-memory or reserved DIR")
        } else if v & (1 << 8) != 0 {
            Some("circular mode")
        } else if v & (1 << 18) != 0 {
            Some("double-buffer mode")
        } else if v & (1 << 9) != 0 {
            Some("peripheral increment")
        } else if (v >> 11) & 3 != 0 || (v >> 13) & 3 != 0 {
            Some("items other than bytes (PSIZE/MSIZE)")
        } else if (v >> 21) & 0xF != 0 {
            Some("bursts")
        } else if s.fcr & (1 << 2) != 0 {
            Some("FIFO mode (FCR.DMDIS)")
        } else if s.ndtr == 0 {
            Some("NDTR 0")
        } else {
            None
        };
        match bad {
            Some(b) => Err(format!(
                "DMA1 stream {i} enabled with {b} (CR 0x{v:08X}): not modelled"
            )),
            None => Ok(()),
        }
    }

    fn flags(&self, s: usize) -> u32 {
        (self.isr[s / 4] >> flag_shift(s)) & 0x3D
    }

    fn set_flag(&mut self, s: usize, f: u32) {
        self.isr[s / 4] |= f << flag_shift(s);
    }

    /// The stream's channel (CHSEL).
    pub fn channel(&self, s: usize) -> u32 {
        (self.streams[s].cr >> 25) & 7
    }

    /// A peripheral's request on stream `s` for channel `ch` whose data
    /// register is at `periph_addr`: the item to move now, if the stream
    /// is enabled for it. Fails when the stream is enabled for another
    /// channel or address (a wiring the image does not have).
    pub fn request(&self, s: usize, ch: u32, periph_addr: u32) -> Access<Option<Item>> {
        let st = &self.streams[s];
        if st.cr & cr::EN == 0 || st.ndtr == 0 {
            return Ok(None);
        }
        if self.channel(s) != ch || st.par != periph_addr {
            return Err(format!(
                "DMA1 stream {s} serves channel {} at 0x{:08X}, but the request is channel {ch}'s at 0x{periph_addr:08X}",
                self.channel(s),
                st.par
            ));
        }
        let dir = if (st.cr >> 6) & 3 == 0 {
            Dir::PeriphToMem
        } else {
            Dir::MemToPeriph
        };
        let minc = st.cr & (1 << 10) != 0;
        Ok(Some(Item {
            stream: s,
            dir,
            mem_addr: st.m0ar + if minc { st.moved } else { 0 },
        }))
    }

    /// The item of [`Self::request`] moved: NDTR down, HTIF/TCIF.
    pub fn item_done(&mut self, s: usize) {
        self.items += 1;
        let st = &mut self.streams[s];
        let total = st.ndtr + st.moved;
        st.moved += 1;
        st.ndtr -= 1;
        let (ndtr, moved) = (st.ndtr, st.moved);
        if ndtr == 0 {
            st.cr &= !cr::EN;
            self.set_flag(s, TCIF);
        }
        if moved == total.div_ceil(2) {
            self.set_flag(s, HTIF);
        }
    }

    /// Stream `s`'s interrupt line.
    pub fn irq(&self, s: usize) -> bool {
        let f = self.flags(s);
        let c = self.streams[s].cr;
        (f & TCIF != 0 && c & cr::TCIE != 0)
            || (f & HTIF != 0 && c & cr::HTIE != 0)
            || (f & TEIF != 0 && c & cr::TEIE != 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RM0383 §9.5: reset values (FCR 0x21, the rest 0); a byte stream of
    /// three items counts NDTR down, sets TCIF at the end with EN cleared,
    /// and the interrupt line follows TCIE; LIFCR clears the flag.
    #[test]
    fn stream_counts_down_to_tcif() {
        let mut d = Dma::default();
        let s0 = 0x10;
        assert_eq!(d.read(s0 + 0x14).unwrap(), 0x21);
        assert_eq!(d.read(s0).unwrap(), 0);
        d.write(s0 + 0x04, 3, !0).unwrap();
        d.write(s0 + 0x08, 0x4000_5410, !0).unwrap();
        d.write(s0 + 0x0C, 0x2000_0100, !0).unwrap();
        // CHSEL 1, MINC, TCIE, TEIE, peripheral-to-memory.
        let cr = (1 << 25) | (1 << 10) | cr::TCIE | cr::TEIE;
        d.write(s0, cr, !0).unwrap();
        assert_eq!(d.request(0, 1, 0x4000_5410).unwrap(), None, "not enabled");
        d.write(s0, cr | cr::EN, !0).unwrap();
        for i in 0..3 {
            let it = d.request(0, 1, 0x4000_5410).unwrap().unwrap();
            assert_eq!(it.mem_addr, 0x2000_0100 + i);
            assert_eq!(it.dir, Dir::PeriphToMem);
            assert!(!d.irq(0));
            d.item_done(0);
        }
        assert_eq!(d.read(s0 + 0x04).unwrap(), 0);
        assert_eq!(d.read(s0).unwrap() & cr::EN, 0, "EN cleared at the end");
        assert_eq!(d.read(0x00).unwrap() & (TCIF | HTIF), TCIF | HTIF);
        assert!(d.irq(0));
        d.write(0x08, TCIF | HTIF, !0).unwrap();
        assert!(!d.irq(0));
        // Another channel's request on the stream is a wiring error.
        d.write(s0 + 0x04, 1, !0).unwrap();
        d.write(s0, cr | cr::EN, !0).unwrap();
        assert!(d.request(0, 2, 0x4000_5410).is_err());
        // Stream 6's flags sit at bit 16 of HISR.
        assert_eq!(flag_shift(6), 16);
    }
}
