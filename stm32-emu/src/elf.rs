//! The release ELF: its loadable segments (at their load addresses, as a
//! flasher writes them) and its symbols by name.

use object::{Object, ObjectSegment, ObjectSymbol};

/// A loaded image.
#[derive(Clone, Debug)]
pub struct Image {
    /// (load address, bytes) of every PT_LOAD segment with file data.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// Symbols: (name, address, size).
    pub symbols: Vec<(String, u32, u32)>,
}

impl Image {
    /// Parses `bytes`; an error names what is wrong.
    pub fn parse(bytes: &[u8]) -> Result<Self, String> {
        let file = object::File::parse(bytes).map_err(|e| format!("not an ELF file: {e}"))?;
        if file.architecture() != object::Architecture::Arm {
            return Err(format!(
                "not an ARM image (architecture {:?})",
                file.architecture()
            ));
        }
        let mut segments = Vec::new();
        for seg in file.segments() {
            let data = seg.data().map_err(|e| format!("segment data: {e}"))?;
            if data.is_empty() {
                continue;
            }
            // The load (physical) address: .data's initial values sit in flash.
            let (off, _) = seg.file_range();
            let paddr = load_address(bytes, off).unwrap_or(seg.address());
            segments.push((paddr as u32, data.to_vec()));
        }
        let symbols = file
            .symbols()
            .filter_map(|s| {
                Some((
                    s.name().ok()?.to_string(),
                    s.address() as u32,
                    s.size() as u32,
                ))
            })
            .collect();
        Ok(Self { segments, symbols })
    }

    /// The address of the first symbol whose name starts with `prefix`
    /// (a Rust static's mangled name without its hash).
    pub fn symbol_prefix(&self, prefix: &str) -> Option<u32> {
        self.symbols
            .iter()
            .find(|s| s.0.starts_with(prefix))
            .map(|s| s.1 & !1)
    }

    /// The address of symbol `name` (thumb bit cleared).
    pub fn symbol(&self, name: &str) -> Option<u32> {
        self.symbols.iter().find(|s| s.0 == name).map(|s| s.1 & !1)
    }
}

/// The p_paddr of the ELF32 program header whose p_offset is `file_off`.
fn load_address(bytes: &[u8], file_off: u64) -> Option<u64> {
    let u32_at = |o: usize| -> Option<u32> {
        Some(u32::from_le_bytes(bytes.get(o..o + 4)?.try_into().ok()?))
    };
    let u16_at = |o: usize| -> Option<u16> {
        Some(u16::from_le_bytes(bytes.get(o..o + 2)?.try_into().ok()?))
    };
    if bytes.get(4) != Some(&1) {
        return None; // not ELF32
    }
    let phoff = u32_at(0x1C)? as usize;
    let phentsize = u16_at(0x2A)? as usize;
    let phnum = u16_at(0x2C)? as usize;
    (0..phnum).find_map(|i| {
        let h = phoff + i * phentsize;
        (u32_at(h)? == 1 && u32_at(h + 4)? as u64 == file_off)
            .then(|| u32_at(h + 12).map(u64::from))?
    })
}
