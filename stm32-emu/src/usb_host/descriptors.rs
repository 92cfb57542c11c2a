//! Descriptor parsing and checking from the specifications: USB 2.0
//! chapter 9 (§9.6: device, configuration, interface, endpoint, string),
//! the Interface Association Descriptor ECN (USB 2.0 ECN, 2003) and CDC
//! 1.2 with its PSTN subclass 1.2 (header, call management, abstract
//! control management and union functional descriptors). Every check names
//! the descriptor, the field, the value and what the specification allows.

use core::fmt;

/// A descriptor that breaks the specification.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DescError {
    /// A field's value is not allowed.
    Field {
        /// Which descriptor ("device", "endpoint 0x81", ...).
        desc: String,
        /// The field's name as the specification spells it.
        field: &'static str,
        /// Its value.
        value: u32,
        /// What the specification allows, and where.
        expected: &'static str,
    },
    /// Fewer bytes than the descriptor needs.
    Truncated {
        /// Which descriptor.
        desc: String,
        /// Bytes needed.
        need: usize,
        /// Bytes there.
        got: usize,
    },
    /// A descriptor the function needs is not there.
    Missing {
        /// What is missing.
        what: &'static str,
    },
}

impl fmt::Display for DescError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Field {
                desc,
                field,
                value,
                expected,
            } => write!(
                f,
                "{desc} descriptor: {field} = {value} (0x{value:X}), expected {expected}"
            ),
            Self::Truncated { desc, need, got } => {
                write!(f, "{desc} descriptor: {got} B, needs {need} B")
            }
            Self::Missing { what } => write!(f, "configuration: no {what}"),
        }
    }
}

impl std::error::Error for DescError {}

/// Descriptor types (USB 2.0 Table 9-5, IAD ECN, CDC 1.2 Table 12).
pub mod dtype {
    /// DEVICE.
    pub const DEVICE: u8 = 1;
    /// CONFIGURATION.
    pub const CONFIGURATION: u8 = 2;
    /// STRING.
    pub const STRING: u8 = 3;
    /// INTERFACE.
    pub const INTERFACE: u8 = 4;
    /// ENDPOINT.
    pub const ENDPOINT: u8 = 5;
    /// INTERFACE ASSOCIATION (IAD ECN).
    pub const IAD: u8 = 11;
    /// CS_INTERFACE (CDC 1.2 Table 12).
    pub const CS_INTERFACE: u8 = 0x24;
}

fn field(desc: &str, field: &'static str, value: u32, expected: &'static str) -> DescError {
    DescError::Field {
        desc: desc.to_string(),
        field,
        value,
        expected,
    }
}

fn need(desc: &str, b: &[u8], n: usize) -> Result<(), DescError> {
    if b.len() < n {
        return Err(DescError::Truncated {
            desc: desc.to_string(),
            need: n,
            got: b.len(),
        });
    }
    Ok(())
}

fn le16(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}

/// The device descriptor (USB 2.0 §9.6.1).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceDesc {
    /// bcdUSB.
    pub bcd_usb: u16,
    /// bDeviceClass, bDeviceSubClass, bDeviceProtocol.
    pub class: (u8, u8, u8),
    /// bMaxPacketSize0.
    pub max_packet_size0: u8,
    /// idVendor, idProduct.
    pub vid_pid: (u16, u16),
    /// iManufacturer, iProduct, iSerialNumber.
    pub strings: [u8; 3],
    /// bNumConfigurations.
    pub num_configurations: u8,
}

/// The first 8 bytes of the device descriptor (what a host reads before
/// it knows bMaxPacketSize0): length, type, and bMaxPacketSize0.
pub fn device_head(b: &[u8]) -> Result<u8, DescError> {
    need("device", b, 8)?;
    if b[0] != 18 {
        return Err(field(
            "device",
            "bLength",
            b[0] as u32,
            "18 (USB 2.0 Table 9-8)",
        ));
    }
    if b[1] != dtype::DEVICE {
        return Err(field(
            "device",
            "bDescriptorType",
            b[1] as u32,
            "1 = DEVICE (Table 9-5)",
        ));
    }
    match b[7] {
        8 | 16 | 32 | 64 => Ok(b[7]),
        v => Err(field(
            "device",
            "bMaxPacketSize0",
            v as u32,
            "8, 16, 32 or 64 at full speed (USB 2.0 §5.5.3)",
        )),
    }
}

/// Parses and checks the whole device descriptor.
pub fn device(b: &[u8]) -> Result<DeviceDesc, DescError> {
    device_head(b)?;
    need("device", b, 18)?;
    if b.len() != 18 {
        return Err(DescError::Truncated {
            desc: "device (more bytes than bLength)".into(),
            need: 18,
            got: b.len(),
        });
    }
    let bcd_usb = le16(b, 2);
    if !matches!(bcd_usb, 0x0110 | 0x0200 | 0x0201 | 0x0210) {
        return Err(field(
            "device",
            "bcdUSB",
            bcd_usb as u32,
            "0x0110, 0x0200, 0x0201 or 0x0210 (USB 2.0 §9.6.1, BCD)",
        ));
    }
    let class = (b[4], b[5], b[6]);
    // 0: per interface; 0xEF/0x02/0x01: a composite device with IADs
    // (IAD ECN §2); 0x02: a CDC device (CDC 1.2 §5.1.1).
    if !matches!(class, (0, 0, 0) | (0xEF, 2, 1) | (2, _, _)) {
        return Err(field(
            "device",
            "bDeviceClass",
            class.0 as u32,
            "0 (per interface), 0xEF with subclass 2 protocol 1 (IAD ECN) or 2 (CDC)",
        ));
    }
    let n = b[17];
    if n == 0 {
        return Err(field(
            "device",
            "bNumConfigurations",
            0,
            "at least 1 (USB 2.0 §9.6.1)",
        ));
    }
    Ok(DeviceDesc {
        bcd_usb,
        class,
        max_packet_size0: b[7],
        vid_pid: (le16(b, 8), le16(b, 10)),
        strings: [b[14], b[15], b[16]],
        num_configurations: n,
    })
}

/// The configuration descriptor's first 9 bytes: wTotalLength.
pub fn config_head(b: &[u8]) -> Result<u16, DescError> {
    need("configuration", b, 9)?;
    if b[0] != 9 {
        return Err(field(
            "configuration",
            "bLength",
            b[0] as u32,
            "9 (USB 2.0 Table 9-10)",
        ));
    }
    if b[1] != dtype::CONFIGURATION {
        return Err(field(
            "configuration",
            "bDescriptorType",
            b[1] as u32,
            "2 = CONFIGURATION (Table 9-5)",
        ));
    }
    let total = le16(b, 2);
    if total < 9 {
        return Err(field(
            "configuration",
            "wTotalLength",
            total as u32,
            "at least 9",
        ));
    }
    Ok(total)
}

/// An endpoint (USB 2.0 §9.6.6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Endpoint {
    /// bEndpointAddress (bit 7: IN).
    pub address: u8,
    /// Transfer type (bmAttributes 1:0): 2 bulk, 3 interrupt.
    pub kind: u8,
    /// wMaxPacketSize.
    pub max_packet_size: u16,
    /// bInterval \[frames\].
    pub interval: u8,
}

/// A CDC-ACM function found in the configuration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CdcAcm {
    /// The communication class interface.
    pub comm_interface: u8,
    /// The data class interface.
    pub data_interface: u8,
    /// The notification endpoint (interrupt IN).
    pub notify: Endpoint,
    /// Bulk IN.
    pub bulk_in: Endpoint,
    /// Bulk OUT.
    pub bulk_out: Endpoint,
    /// bcdCDC of the header functional descriptor.
    pub bcd_cdc: u16,
    /// bmCapabilities of the ACM functional descriptor.
    pub acm_capabilities: u8,
}

/// The whole configuration, parsed and checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    /// bConfigurationValue.
    pub value: u8,
    /// bNumInterfaces.
    pub num_interfaces: u8,
    /// bMaxPower \[2 mA\].
    pub max_power: u8,
    /// The CDC-ACM function.
    pub acm: CdcAcm,
}

#[derive(Default)]
struct Iface {
    number: u8,
    class: (u8, u8, u8),
    num_endpoints: u8,
    endpoints: Vec<Endpoint>,
    header: Option<u16>,
    call_mgmt: Option<(u8, u8)>,
    acm: Option<u8>,
    union: Option<(u8, Vec<u8>)>,
    functional_seen: bool,
}

/// Parses and checks a configuration (the descriptor and everything its
/// wTotalLength covers) for one CDC-ACM function as the firmware exposes
/// it: an IAD over the two interfaces (class 2/2), the communication
/// interface (class 2, subclass 2 = ACM) with its functional descriptors
/// and an interrupt IN endpoint, the data interface (class 0x0A) with a
/// bulk IN and a bulk OUT endpoint.
pub fn config(b: &[u8]) -> Result<Config, DescError> {
    let total = config_head(b)? as usize;
    if b.len() != total {
        return Err(field(
            "configuration",
            "wTotalLength",
            total as u32,
            "the bytes the device returned for the whole configuration",
        ));
    }
    let num_interfaces = b[4];
    let value = b[5];
    if value == 0 {
        return Err(field(
            "configuration",
            "bConfigurationValue",
            0,
            "at least 1 (0 means unconfigured, USB 2.0 §9.4.7)",
        ));
    }
    let attrs = b[7];
    if attrs & 0x80 == 0 || attrs & 0x1F != 0 {
        return Err(field(
            "configuration",
            "bmAttributes",
            attrs as u32,
            "bit 7 set, bits 4..0 zero (USB 2.0 Table 9-10)",
        ));
    }
    let mut ifaces: Vec<Iface> = Vec::new();
    let mut iad: Option<(u8, u8, (u8, u8, u8))> = None;
    let mut addrs: Vec<u8> = Vec::new();
    let mut i = 9;
    while i < total {
        let len = b[i] as usize;
        if len < 2 || i + len > total {
            return Err(field(
                "configuration",
                "bLength",
                len as u32,
                "at least 2 and within wTotalLength (USB 2.0 §9.5)",
            ));
        }
        let d = &b[i..i + len];
        match d[1] {
            dtype::IAD => {
                if len != 8 {
                    return Err(field(
                        "interface association",
                        "bLength",
                        len as u32,
                        "8 (IAD ECN Table 9-Z)",
                    ));
                }
                if !ifaces.is_empty() || iad.is_some() {
                    return Err(field(
                        "interface association",
                        "bFirstInterface",
                        d[2] as u32,
                        "an IAD before the interfaces it groups (IAD ECN §9.6.4)",
                    ));
                }
                if d[3] < 2 {
                    return Err(field(
                        "interface association",
                        "bInterfaceCount",
                        d[3] as u32,
                        "at least 2",
                    ));
                }
                iad = Some((d[2], d[3], (d[4], d[5], d[6])));
            }
            dtype::INTERFACE => {
                if len != 9 {
                    return Err(field(
                        "interface",
                        "bLength",
                        len as u32,
                        "9 (USB 2.0 Table 9-12)",
                    ));
                }
                if d[3] != 0 {
                    return Err(field(
                        "interface",
                        "bAlternateSetting",
                        d[3] as u32,
                        "0 (no alternate settings here)",
                    ));
                }
                if let Some(prev) = ifaces.last() {
                    if prev.endpoints.len() != prev.num_endpoints as usize {
                        return Err(field(
                            &format!("interface {}", prev.number),
                            "bNumEndpoints",
                            prev.num_endpoints as u32,
                            "the endpoint descriptors that follow the interface",
                        ));
                    }
                }
                if d[2] as usize != ifaces.len() {
                    return Err(field(
                        "interface",
                        "bInterfaceNumber",
                        d[2] as u32,
                        "numbered from 0 without gaps (USB 2.0 §9.6.5)",
                    ));
                }
                ifaces.push(Iface {
                    number: d[2],
                    class: (d[5], d[6], d[7]),
                    num_endpoints: d[4],
                    ..Default::default()
                });
            }
            dtype::ENDPOINT => {
                let Some(cur) = ifaces.last_mut() else {
                    return Err(DescError::Missing {
                        what: "interface before an endpoint",
                    });
                };
                let name = format!("endpoint 0x{:02X}", d.get(2).copied().unwrap_or(0));
                if len != 7 {
                    return Err(field(
                        &name,
                        "bLength",
                        len as u32,
                        "7 (USB 2.0 Table 9-13)",
                    ));
                }
                let address = d[2];
                if address & 0x70 != 0 || address & 0x0F == 0 {
                    return Err(field(
                        &name,
                        "bEndpointAddress",
                        address as u32,
                        "bits 6..4 zero and an endpoint number 1-15 (USB 2.0 Table 9-13)",
                    ));
                }
                if addrs.contains(&address) {
                    return Err(field(
                        &name,
                        "bEndpointAddress",
                        address as u32,
                        "each address once per configuration",
                    ));
                }
                addrs.push(address);
                let kind = d[3] & 3;
                if d[3] & !3 != 0 {
                    return Err(field(
                        &name,
                        "bmAttributes",
                        d[3] as u32,
                        "bits 7..2 zero for bulk and interrupt",
                    ));
                }
                let mps = le16(d, 4);
                let ok = match kind {
                    2 => matches!(mps, 8 | 16 | 32 | 64),
                    3 => (1..=64).contains(&mps),
                    _ => false,
                };
                if kind == 0 || kind == 1 {
                    return Err(field(&name, "bmAttributes", d[3] as u32, "bulk (2) or interrupt (3): this function has no control or isochronous endpoints"));
                }
                if !ok {
                    return Err(field(
                        &name,
                        "wMaxPacketSize",
                        mps as u32,
                        "8, 16, 32 or 64 for full-speed bulk, 1-64 for interrupt (USB 2.0 §5.8.3, §5.7.3)",
                    ));
                }
                let interval = d[6];
                if kind == 3 && interval == 0 {
                    return Err(field(
                        &name,
                        "bInterval",
                        0,
                        "1-255 frames for a full-speed interrupt endpoint (Table 9-13)",
                    ));
                }
                cur.endpoints.push(Endpoint {
                    address,
                    kind,
                    max_packet_size: mps,
                    interval,
                });
            }
            dtype::CS_INTERFACE => {
                let Some(cur) = ifaces.last_mut() else {
                    return Err(DescError::Missing {
                        what: "interface before a CDC functional descriptor",
                    });
                };
                let sub = d.get(2).copied().unwrap_or(0xFF);
                if !cur.functional_seen && sub != 0 {
                    return Err(field(
                        "CDC functional",
                        "bDescriptorSubtype",
                        sub as u32,
                        "0 (Header) first (CDC 1.2 §5.2.3)",
                    ));
                }
                cur.functional_seen = true;
                match sub {
                    0 => {
                        if len != 5 {
                            return Err(field(
                                "CDC header",
                                "bFunctionLength",
                                len as u32,
                                "5 (CDC 1.2 Table 15)",
                            ));
                        }
                        let bcd = le16(d, 3);
                        if !matches!(bcd, 0x0110 | 0x0120) {
                            return Err(field(
                                "CDC header",
                                "bcdCDC",
                                bcd as u32,
                                "0x0110 or 0x0120 (CDC 1.2 Table 15)",
                            ));
                        }
                        cur.header = Some(bcd);
                    }
                    1 => {
                        if len != 5 {
                            return Err(field(
                                "CDC call management",
                                "bFunctionLength",
                                len as u32,
                                "5 (PSTN 1.2 Table 3)",
                            ));
                        }
                        cur.call_mgmt = Some((d[3], d[4]));
                    }
                    2 => {
                        if len != 4 {
                            return Err(field(
                                "CDC abstract control management",
                                "bFunctionLength",
                                len as u32,
                                "4 (PSTN 1.2 Table 4)",
                            ));
                        }
                        if d[3] & 0xF0 != 0 {
                            return Err(field(
                                "CDC abstract control management",
                                "bmCapabilities",
                                d[3] as u32,
                                "bits 7..4 reserved, zero (PSTN 1.2 Table 4)",
                            ));
                        }
                        cur.acm = Some(d[3]);
                    }
                    6 => {
                        if len < 5 {
                            return Err(field(
                                "CDC union",
                                "bFunctionLength",
                                len as u32,
                                "at least 5 (CDC 1.2 Table 16)",
                            ));
                        }
                        cur.union = Some((d[3], d[4..].to_vec()));
                    }
                    _ => {}
                }
            }
            _ => {}
        }
        i += len;
    }
    if let Some(prev) = ifaces.last() {
        if prev.endpoints.len() != prev.num_endpoints as usize {
            return Err(field(
                &format!("interface {}", prev.number),
                "bNumEndpoints",
                prev.num_endpoints as u32,
                "the endpoint descriptors that follow the interface",
            ));
        }
    }
    if num_interfaces as usize != ifaces.len() {
        return Err(field(
            "configuration",
            "bNumInterfaces",
            num_interfaces as u32,
            "the interface descriptors in the configuration (USB 2.0 Table 9-10)",
        ));
    }
    // The communication interface (CDC 1.2 §4.2: class 2; PSTN: subclass
    // 2 = Abstract Control Model).
    let comm = ifaces
        .iter()
        .find(|f| f.class.0 == 2)
        .ok_or(DescError::Missing {
            what: "communication class interface (class 2)",
        })?;
    let cname = format!("interface {}", comm.number);
    if comm.class.1 != 2 {
        return Err(field(
            &cname,
            "bInterfaceSubClass",
            comm.class.1 as u32,
            "2 = Abstract Control Model (CDC 1.2 Table 4)",
        ));
    }
    if comm.class.2 > 1 && comm.class.2 != 0xFF {
        return Err(field(
            &cname,
            "bInterfaceProtocol",
            comm.class.2 as u32,
            "0 (none) or 1 (AT commands) (CDC 1.2 Table 5)",
        ));
    }
    let bcd_cdc = comm.header.ok_or(DescError::Missing {
        what: "CDC header functional descriptor",
    })?;
    let acm_capabilities = comm.acm.ok_or(DescError::Missing {
        what: "CDC abstract control management functional descriptor",
    })?;
    let (ctrl, subs) = comm.union.clone().ok_or(DescError::Missing {
        what: "CDC union functional descriptor",
    })?;
    if ctrl != comm.number {
        return Err(field(
            "CDC union",
            "bControlInterface",
            ctrl as u32,
            "the communication interface's number (CDC 1.2 Table 16)",
        ));
    }
    let data_no = subs[0];
    let data = ifaces
        .iter()
        .find(|f| f.number == data_no)
        .ok_or(DescError::Missing {
            what: "data interface named by the union's bSubordinateInterface0",
        })?;
    let dname = format!("interface {}", data.number);
    if data.class.0 != 0x0A {
        return Err(field(
            &dname,
            "bInterfaceClass",
            data.class.0 as u32,
            "0x0A = CDC data (CDC 1.2 Table 6), the union's subordinate",
        ));
    }
    if let Some((_, di)) = comm.call_mgmt {
        if di != data_no {
            return Err(field(
                "CDC call management",
                "bDataInterface",
                di as u32,
                "the union's data interface (PSTN 1.2 Table 3)",
            ));
        }
    }
    let notify = *comm
        .endpoints
        .iter()
        .find(|e| e.kind == 3 && e.address & 0x80 != 0)
        .ok_or(DescError::Missing {
            what: "interrupt IN notification endpoint on the communication interface",
        })?;
    if comm.endpoints.len() != 1 {
        return Err(field(
            &cname,
            "bNumEndpoints",
            comm.endpoints.len() as u32,
            "1 (the notification endpoint, CDC 1.2 §3.4.1)",
        ));
    }
    let bulk_in = *data
        .endpoints
        .iter()
        .find(|e| e.kind == 2 && e.address & 0x80 != 0)
        .ok_or(DescError::Missing {
            what: "bulk IN endpoint on the data interface",
        })?;
    let bulk_out = *data
        .endpoints
        .iter()
        .find(|e| e.kind == 2 && e.address & 0x80 == 0)
        .ok_or(DescError::Missing {
            what: "bulk OUT endpoint on the data interface",
        })?;
    if data.endpoints.len() != 2 {
        return Err(field(
            &dname,
            "bNumEndpoints",
            data.endpoints.len() as u32,
            "2 (bulk IN and OUT, CDC 1.2 §3.4.2)",
        ));
    }
    // The IAD (required for a class-0xEF device; IAD ECN §2): it groups the
    // two interfaces, with the communication interface's class.
    if let Some((first, count, class)) = iad {
        if first != comm.number {
            return Err(field(
                "interface association",
                "bFirstInterface",
                first as u32,
                "the communication interface's number",
            ));
        }
        if count != 2 || data_no != first + 1 {
            return Err(field(
                "interface association",
                "bInterfaceCount",
                count as u32,
                "2 (communication and data interfaces, contiguous)",
            ));
        }
        if class.0 != 2 || class.1 != 2 {
            return Err(field(
                "interface association",
                "bFunctionClass",
                class.0 as u32,
                "2 with subclass 2 (the communication interface's class, IAD ECN)",
            ));
        }
    }
    Ok(Config {
        value,
        num_interfaces,
        max_power: b[8],
        acm: CdcAcm {
            comm_interface: comm.number,
            data_interface: data_no,
            notify,
            bulk_in,
            bulk_out,
            bcd_cdc,
            acm_capabilities,
        },
    })
}

/// String descriptor zero: the LANGIDs (USB 2.0 §9.6.7, Table 9-15).
pub fn langids(b: &[u8]) -> Result<Vec<u16>, DescError> {
    need("string 0", b, 4)?;
    if b[1] != dtype::STRING {
        return Err(field(
            "string 0",
            "bDescriptorType",
            b[1] as u32,
            "3 = STRING",
        ));
    }
    let len = b[0] as usize;
    if len != b.len() || len % 2 != 0 || len < 4 {
        return Err(field(
            "string 0",
            "bLength",
            len as u32,
            "an even count of at least 4, the bytes returned",
        ));
    }
    Ok(b[2..]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect())
}

/// A string descriptor (USB 2.0 Table 9-16): UTF-16LE.
pub fn string(index: u8, b: &[u8]) -> Result<String, DescError> {
    let name = format!("string {index}");
    need(&name, b, 2)?;
    if b[1] != dtype::STRING {
        return Err(field(&name, "bDescriptorType", b[1] as u32, "3 = STRING"));
    }
    let len = b[0] as usize;
    if len != b.len() || len % 2 != 0 {
        return Err(field(
            &name,
            "bLength",
            len as u32,
            "an even count, the bytes returned",
        ));
    }
    let units: Vec<u16> = b[2..]
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    String::from_utf16(&units)
        .map_err(|_| field(&name, "bString", 0, "valid UTF-16LE (USB 2.0 §9.6.7)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A CDC-ACM device descriptor written from USB 2.0 Table 9-8 and the
    /// IAD ECN: composite class 0xEF/2/1, EP0 64 B, one configuration.
    fn dev() -> Vec<u8> {
        vec![
            18, 1, 0x10, 0x02, 0xEF, 0x02, 0x01, 64, 0x09, 0x12, 0x01, 0x00, 0x00, 0x01, 1, 2, 3, 1,
        ]
    }

    /// The configuration of a CDC-ACM function from CDC 1.2 / PSTN 1.2's
    /// examples: IAD, comm interface 0 (class 2/2/0) with header, call
    /// management, ACM and union descriptors and an interrupt IN 0x81
    /// (8 B, 255 frames), data interface 1 (0x0A) with bulk OUT 0x02 and
    /// bulk IN 0x82 (64 B).
    fn cfg() -> Vec<u8> {
        let mut v = vec![9, 2, 0, 0, 2, 1, 0, 0x80, 50];
        v.extend([8, 11, 0, 2, 2, 2, 0, 0]);
        v.extend([9, 4, 0, 0, 1, 2, 2, 0, 0]);
        v.extend([5, 0x24, 0, 0x10, 0x01]);
        v.extend([5, 0x24, 1, 0, 1]);
        v.extend([4, 0x24, 2, 0x02]);
        v.extend([5, 0x24, 6, 0, 1]);
        v.extend([7, 5, 0x81, 3, 8, 0, 255]);
        v.extend([9, 4, 1, 0, 2, 0x0A, 0, 0, 0]);
        v.extend([7, 5, 0x02, 2, 64, 0, 0]);
        v.extend([7, 5, 0x82, 2, 64, 0, 0]);
        let n = v.len() as u16;
        v[2..4].copy_from_slice(&n.to_le_bytes());
        v
    }

    #[test]
    fn valid_descriptors_parse() {
        let d = device(&dev()).unwrap();
        assert_eq!(d.max_packet_size0, 64);
        assert_eq!(d.vid_pid, (0x1209, 0x0001));
        let c = config(&cfg()).unwrap();
        assert_eq!(c.acm.bulk_in.address, 0x82);
        assert_eq!(c.acm.bulk_out.address, 0x02);
        assert_eq!(c.acm.notify.address, 0x81);
        assert_eq!(c.acm.data_interface, 1);
        assert_eq!(langids(&[4, 3, 0x09, 0x04]).unwrap(), vec![0x0409]);
        assert_eq!(string(2, &[6, 3, b'h', 0, b'i', 0]).unwrap(), "hi");
    }

    /// Negative controls: each corrupted field is named in the error.
    #[test]
    fn corrupted_device_descriptor_names_the_field() {
        let cases: &[(usize, u8, &str)] = &[
            (0, 17, "bLength"),
            (1, 2, "bDescriptorType"),
            (7, 65, "bMaxPacketSize0"),
            (3, 0x03, "bcdUSB"),
            (4, 0xFF, "bDeviceClass"),
            (17, 0, "bNumConfigurations"),
        ];
        for &(i, v, name) in cases {
            let mut d = dev();
            d[i] = v;
            let e = device(&d).unwrap_err().to_string();
            assert!(e.contains(name), "byte {i} = {v}: {e}");
        }
        assert!(matches!(
            device(&dev()[..12]),
            Err(DescError::Truncated { .. })
        ));
    }

    #[test]
    fn corrupted_configuration_names_the_field() {
        // (offset in cfg(), new value, field named)
        let cases: &[(usize, u8, &str)] = &[
            (0, 8, "bLength"),
            (1, 4, "bDescriptorType"),
            (4, 3, "bNumInterfaces"),
            (5, 0, "bConfigurationValue"),
            (7, 0x40, "bmAttributes"),
            (9 + 3, 1, "bInterfaceCount"),      // IAD count
            (9 + 4, 3, "bFunctionClass"),       // IAD class
            (17 + 6, 6, "bInterfaceSubClass"),  // comm subclass
            (17 + 4, 2, "bNumEndpoints"),       // comm endpoints
            (26 + 3, 0x99, "bcdCDC"),           // header
            (26 + 2, 1, "bDescriptorSubtype"),  // header not first
            (31 + 4, 0, "bDataInterface"),      // call management
            (36 + 3, 0x12, "bmCapabilities"),   // ACM reserved bits
            (40 + 3, 1, "bControlInterface"),   // union
            (45 + 2, 0x91, "bEndpointAddress"), // notify: reserved bits
            (45 + 6, 0, "bInterval"),           // notify
            (52 + 5, 0x03, "bInterfaceClass"),  // data class
            (61 + 4, 65, "wMaxPacketSize"),     // bulk OUT
            (68 + 2, 0x02, "bEndpointAddress"), // duplicate address
            (68 + 3, 1, "bmAttributes"),        // isochronous
            (52 + 2, 2, "bInterfaceNumber"),
        ];
        for &(i, v, name) in cases {
            let mut c = cfg();
            c[i] = v;
            let e = config(&c).unwrap_err().to_string();
            assert!(
                e.contains(name),
                "byte {i} = 0x{v:02X}: expected {name}: {e}"
            );
        }
        let mut c = cfg();
        c.truncate(c.len() - 1);
        let e = config(&c).unwrap_err().to_string();
        assert!(e.contains("wTotalLength"), "{e}");
        assert!(string(1, &[5, 3, b'h', 0, b'i'])
            .unwrap_err()
            .to_string()
            .contains("bLength"));
        assert!(langids(&[4, 2, 9, 4])
            .unwrap_err()
            .to_string()
            .contains("bDescriptorType"));
    }
}
