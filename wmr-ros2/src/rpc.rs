//! ROS 2 services over DDS: which request/reply mapping a caller uses,
//! read from each request itself (D150), without DDS (the DDS side is
//! [`crate::services`]).
//!
//! The two mappings ROS 2's RMWs use for a service `/s` (topics
//! `rq/sRequest` and `rr/sReply`, types `<pkg>::srv::dds_::<T>_Request_` /
//! `_Response_`), read from their Jazzy sources:
//!
//! - **rmw_fastrtps** (ROS 2's default RMW; `rmw_fastrtps_shared_cpp/src/
//!   rmw_request.cpp`, `rmw_response.cpp`, branch `jazzy`): the payload is
//!   the request alone. The client writes it with a *related sample
//!   identity* (an inline QoS parameter) whose writer GUID is its reply
//!   reader's GUID; the request's id is the DATA's own sample identity. The
//!   server answers with the reply alone and a related sample identity of
//!   (that reader GUID, the request's sequence number); the client takes a
//!   reply whose related GUID is its reader's or its request writer's.
//!   rmw_connextdds's default ("extended") mapping is the same on the wire.
//! - **rmw_cyclonedds** (`rmw_cyclonedds_cpp/src/serdata.hpp`,
//!   `rmw_node.cpp`, branch `jazzy`): the payload starts with
//!   `cdds_request_header_t { uint64_t guid; int64_t seq; }` (the guid is the
//!   client's request writer's instance handle, not a GUID), then the
//!   request; no inline QoS. The reply carries the same 16-byte header
//!   first; the client takes replies whose header guid is its own.
//!
//! So a request with a related sample identity is a Fast DDS (enhanced)
//! caller's; one without is a CycloneDDS caller's, and must then hold a
//! 16-byte header and a request that fills the rest (up to CDR's 3 bytes of
//! padding). Anything else cannot be answered in a form its caller decodes:
//! it is refused and never acted on (before issue 35 an enhanced-only
//! bridge read a CycloneDDS caller's header as the request, armed the robot
//! and sent a reply the caller could not decode).

use serde::de::DeserializeOwned;
use serde::Serialize;

/// A request/reply mapping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mapping {
    /// No header in the payload, ids in inline QoS (rmw_fastrtps,
    /// rmw_connextdds "extended"; RPC over DDS "enhanced").
    Enhanced,
    /// rmw_cyclonedds's 16-byte header in the payload.
    Cyclone,
}

impl std::fmt::Display for Mapping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Enhanced => "enhanced (rmw_fastrtps)",
            Self::Cyclone => "cyclone (rmw_cyclonedds)",
        })
    }
}

/// Which callers the bridge answers (`--service-mapping`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accept {
    /// Each request's own mapping (the default).
    Auto,
    /// Only callers of this mapping; the others are refused.
    Only(Mapping),
}

/// Bytes of rmw_cyclonedds's request/reply header.
pub const CYCLONE_HEADER_BYTES: usize = 16;

/// CDR pads a payload to a multiple of 4 bytes.
const MAX_PADDING_BYTES: usize = 3;

/// A sample identity: a writer's GUID and a sequence number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleId {
    /// The GUID (prefix and entity id).
    pub guid: [u8; 16],
    /// The sequence number.
    pub seq: i64,
}

/// One request as DDS delivered it.
#[derive(Clone, Copy, Debug)]
pub struct Incoming<'a> {
    /// The serialized payload after its 4-byte encapsulation header.
    pub payload: &'a [u8],
    /// Little-endian CDR (else big-endian).
    pub little_endian: bool,
    /// The DATA's own identity: the request writer and its sequence number.
    pub sample: SampleId,
    /// The related sample identity of its inline QoS, if any.
    pub related: Option<SampleId>,
}

/// How to answer one request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Call {
    /// The caller's mapping.
    pub mapping: Mapping,
    /// Where the request starts in the payload.
    pub body_offset: usize,
    /// The reply's payload header (rmw_cyclonedds's, little-endian; empty
    /// for enhanced).
    pub reply_header: Vec<u8>,
    /// The reply's related sample identity (inline QoS).
    pub reply_related: SampleId,
}

/// Why a request is not answered (nor acted on).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Unanswerable {
    /// The caller's mapping is not the one `--service-mapping` accepts.
    #[error("a caller using the {got} service mapping, but --service-mapping accepts {want} only (use --service-mapping auto)")]
    NotAccepted {
        /// The caller's.
        got: Mapping,
        /// The accepted one.
        want: Mapping,
    },
    /// No related sample identity and no room for rmw_cyclonedds's header.
    #[error("a request of {len} bytes without a related sample identity: neither rmw_fastrtps's (which always sends one) nor rmw_cyclonedds's (a {CYCLONE_HEADER_BYTES}-byte header first); not answered")]
    UnknownMapping {
        /// Payload bytes.
        len: usize,
    },
    /// The request does not decode as the service's type.
    #[error("the {mapping} request does not decode as the service's request type: {reason}")]
    Malformed {
        /// The mapping it was read with.
        mapping: Mapping,
        /// The decoder's reason.
        reason: String,
    },
    /// The request leaves bytes over (another type or another header).
    #[error("the {mapping} request leaves {extra} bytes after the service's request type (more than CDR's {MAX_PADDING_BYTES} of padding): another type or another mapping's header")]
    TrailingBytes {
        /// The mapping it was read with.
        mapping: Mapping,
        /// Bytes left.
        extra: usize,
    },
}

fn read_u64(b: &[u8], little_endian: bool) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    if little_endian {
        u64::from_le_bytes(a)
    } else {
        u64::from_be_bytes(a)
    }
}

/// The mapping of one request and how to answer it.
pub fn classify(r: &Incoming, accept: Accept) -> Result<Call, Unanswerable> {
    let call = match r.related {
        Some(rel) => Call {
            mapping: Mapping::Enhanced,
            body_offset: 0,
            reply_header: Vec::new(),
            // rmw_fastrtps's server: the client's reader GUID (what the
            // related identity names) and the request's sequence number.
            reply_related: SampleId {
                guid: if rel.guid == [0; 16] {
                    r.sample.guid
                } else {
                    rel.guid
                },
                seq: r.sample.seq,
            },
        },
        None if r.payload.len() > CYCLONE_HEADER_BYTES => {
            let guid = read_u64(r.payload, r.little_endian);
            let seq = read_u64(&r.payload[8..], r.little_endian);
            let mut h = Vec::with_capacity(CYCLONE_HEADER_BYTES);
            h.extend_from_slice(&guid.to_le_bytes());
            h.extend_from_slice(&seq.to_le_bytes());
            Call {
                mapping: Mapping::Cyclone,
                body_offset: CYCLONE_HEADER_BYTES,
                reply_header: h,
                reply_related: r.sample,
            }
        }
        None => {
            return Err(Unanswerable::UnknownMapping {
                len: r.payload.len(),
            })
        }
    };
    if let Accept::Only(want) = accept {
        if want != call.mapping {
            return Err(Unanswerable::NotAccepted {
                got: call.mapping,
                want,
            });
        }
    }
    Ok(call)
}

/// Decodes the request of `call` from `r`'s payload: the whole rest of it
/// (up to CDR's padding), else refused.
pub fn decode<Q: DeserializeOwned>(r: &Incoming, call: &Call) -> Result<Q, Unanswerable> {
    use ros2_client::dds::rustdds::{serialization, RepresentationIdentifier};
    let rep = if r.little_endian {
        RepresentationIdentifier::CDR_LE
    } else {
        RepresentationIdentifier::CDR_BE
    };
    let body = &r.payload[call.body_offset..];
    let (q, used) =
        serialization::deserialize_from_cdr_with_rep_id::<Q>(body, rep).map_err(|e| {
            Unanswerable::Malformed {
                mapping: call.mapping,
                reason: e.to_string(),
            }
        })?;
    let extra = body.len().saturating_sub(used);
    if extra > MAX_PADDING_BYTES {
        return Err(Unanswerable::TrailingBytes {
            mapping: call.mapping,
            extra,
        });
    }
    Ok(q)
}

/// The reply's payload (after the encapsulation header, little-endian
/// CDR): the mapping's header, then the response.
pub fn reply_payload<S: Serialize>(call: &Call, response: &S) -> Vec<u8> {
    use ros2_client::dds::rustdds::{serialization, RepresentationIdentifier};
    let mut out = call.reply_header.clone();
    // A message of the service's type always serializes (to memory).
    serialization::to_writer_with_rep_id(&mut out, response, RepresentationIdentifier::CDR_LE)
        .expect("CDR serialization to memory");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{TriggerRequest, TriggerResponse};

    const WRITER: [u8; 16] = [1, 15, 0, 0, 9, 9, 9, 9, 2, 0, 0, 0, 0, 0, 3, 3];
    // A reader's entity kind (0x04 bit set), as rmw_fastrtps puts in the
    // related identity of a request.
    const READER: [u8; 16] = [1, 15, 0, 0, 9, 9, 9, 9, 2, 0, 0, 0, 0, 0, 4, 4];

    #[test]
    fn a_fast_dds_request_is_answered_enhanced_to_its_reply_reader() {
        // rmw_fastrtps: the request alone (a Trigger request is one byte,
        // padded to four), related identity = (reply reader, unknown seq).
        let payload = [0u8, 0, 0, 0];
        let r = Incoming {
            payload: &payload,
            little_endian: true,
            sample: SampleId {
                guid: WRITER,
                seq: 7,
            },
            related: Some(SampleId {
                guid: READER,
                seq: -(1 << 32),
            }),
        };
        let call = classify(&r, Accept::Auto).unwrap();
        assert_eq!(call.mapping, Mapping::Enhanced);
        assert_eq!(
            call.reply_related,
            SampleId {
                guid: READER,
                seq: 7
            }
        );
        let _: TriggerRequest = decode(&r, &call).unwrap();
        // The reply is the response alone: it decodes as one.
        let resp = TriggerResponse {
            success: true,
            message: "armed".into(),
        };
        let bytes = reply_payload(&call, &resp);
        let (back, _) =
            ros2_client::dds::rustdds::serialization::deserialize_from_cdr_with_rep_id::<
                TriggerResponse,
            >(
                &bytes,
                ros2_client::dds::rustdds::RepresentationIdentifier::CDR_LE,
            )
            .unwrap();
        assert_eq!(back, resp);
    }

    #[test]
    fn a_cyclone_request_is_answered_with_its_own_header() {
        // cdds_request_header_t { guid: instance handle, seq: int64 }, then
        // the Trigger request's byte.
        let mut payload = Vec::new();
        payload.extend_from_slice(&0x1122_3344_5566_7788u64.to_le_bytes());
        payload.extend_from_slice(&42i64.to_le_bytes());
        payload.extend_from_slice(&[0, 0, 0, 0]);
        let r = Incoming {
            payload: &payload,
            little_endian: true,
            sample: SampleId {
                guid: WRITER,
                seq: 3,
            },
            related: None,
        };
        let call = classify(&r, Accept::Auto).unwrap();
        assert_eq!(call.mapping, Mapping::Cyclone);
        let _: TriggerRequest = decode(&r, &call).unwrap();
        let bytes = reply_payload(
            &call,
            &TriggerResponse {
                success: false,
                message: "no".into(),
            },
        );
        assert_eq!(
            &bytes[..16],
            &payload[..16],
            "the header comes back as sent"
        );
        // A big-endian caller's header is read in its byte order and
        // answered in the reply's (little-endian).
        let mut be = Vec::new();
        be.extend_from_slice(&0x1122_3344_5566_7788u64.to_be_bytes());
        be.extend_from_slice(&42i64.to_be_bytes());
        be.extend_from_slice(&[0, 0, 0, 0]);
        let call_be = classify(
            &Incoming {
                payload: &be,
                little_endian: false,
                ..r
            },
            Accept::Auto,
        )
        .unwrap();
        assert_eq!(call_be.reply_header, payload[..16].to_vec());
    }

    #[test]
    fn what_cannot_be_answered_is_refused() {
        // Enhanced without a related identity (not rmw_fastrtps): a
        // Trigger request of one byte has no room for a Cyclone header.
        let one = [0u8, 0, 0, 0];
        let r = Incoming {
            payload: &one,
            little_endian: true,
            sample: SampleId {
                guid: WRITER,
                seq: 1,
            },
            related: None,
        };
        assert_eq!(
            classify(&r, Accept::Auto),
            Err(Unanswerable::UnknownMapping { len: 4 })
        );
        // A header-less request long enough for a header: the body then
        // decodes wrongly or leaves bytes over.
        let mut long = vec![0u8; 16];
        long.extend_from_slice(&[0u8; 12]);
        let r2 = Incoming {
            payload: &long,
            ..r
        };
        let call = classify(&r2, Accept::Auto).unwrap();
        assert!(matches!(
            decode::<TriggerRequest>(&r2, &call),
            Err(Unanswerable::TrailingBytes { extra: 11, .. })
        ));
        // A mapping other than the one accepted.
        let rf = Incoming {
            related: Some(SampleId {
                guid: READER,
                seq: 0,
            }),
            ..r
        };
        let e = classify(&rf, Accept::Only(Mapping::Cyclone)).unwrap_err();
        assert!(e.to_string().contains("--service-mapping auto"), "{e}");
        assert!(classify(&rf, Accept::Only(Mapping::Enhanced)).is_ok());
    }
}
