//! The bridge's ROS 2 services on DDS, answering each caller in its own
//! request/reply mapping ([`crate::rpc`], D150): a request reader and a
//! reply writer on RustDDS (through ros2-client's re-export) that see the
//! raw payload and the inline QoS, which ros2-client's `Server` (one fixed
//! mapping) does not show.

use crate::rpc::{self, Accept, Call, Incoming, SampleId, Unanswerable};
use crate::topics;
use ros2_client::dds::rustdds::{
    bytes::Bytes,
    no_key::{self, DataWriter, SimpleDataReader},
    rpc::SampleIdentity,
    DomainParticipant, Publisher, QosPolicies, RepresentationIdentifier, SequenceNumber,
    Subscriber, Timestamp, TopicKind, WriteOptionsBuilder, GUID,
};
use serde::{de::DeserializeOwned, Serialize};
use std::marker::PhantomData;

/// A request's payload as received.
pub struct RawRequest {
    bytes: Bytes,
    rep: RepresentationIdentifier,
}

/// A reply's payload as sent (little-endian CDR).
pub struct RawReply(Bytes);

/// Passes payloads through (the mapping decides how to read them).
pub struct RawAdapter;

/// The adapter's error (never produced).
#[derive(Debug, thiserror::Error)]
#[error("raw payload")]
pub struct RawError;

impl no_key::DeserializerAdapter<RawRequest> for RawAdapter {
    type Error = RawError;
    type Decoded = RawRequest;
    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &[
            RepresentationIdentifier::CDR_LE,
            RepresentationIdentifier::CDR_BE,
        ]
    }
    fn transform_decoded(decoded: RawRequest) -> RawRequest {
        decoded
    }
}

/// The decoder of [`RawAdapter`].
#[derive(Clone)]
pub struct RawDecoder;

impl<'de> no_key::Decode<'de, RawRequest> for RawDecoder {
    type Error = RawError;
    fn decode_bytes(
        self,
        input_bytes: &'de [u8],
        encoding: RepresentationIdentifier,
    ) -> Result<RawRequest, RawError> {
        Ok(RawRequest {
            bytes: Bytes::copy_from_slice(input_bytes),
            rep: encoding,
        })
    }
}

impl no_key::DefaultDecoder<RawRequest> for RawAdapter {
    type Decoder = RawDecoder;
    const DECODER: RawDecoder = RawDecoder;
}

impl no_key::SerializerAdapter<RawReply> for RawAdapter {
    type Error = RawError;
    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }
    fn to_bytes(value: &RawReply) -> Result<Bytes, RawError> {
        Ok(value.0.clone())
    }
}

/// Why a service could not be created.
#[derive(Debug, thiserror::Error)]
#[error("service {name}: {reason}")]
pub struct CreateError {
    /// The service.
    pub name: String,
    /// What DDS said.
    pub reason: String,
}

/// The DDS entities services are made from (one publisher, one
/// subscriber).
pub struct ServiceHost {
    dp: DomainParticipant,
    publisher: Publisher,
    subscriber: Subscriber,
    accept: Accept,
}

impl ServiceHost {
    /// On the node's participant, answering the callers `accept` says.
    pub fn new(dp: DomainParticipant, accept: Accept) -> Result<Self, CreateError> {
        let qos: QosPolicies = (&topics::service_qos()).into();
        let err = |e: String| CreateError {
            name: "(publisher/subscriber)".into(),
            reason: e,
        };
        Ok(Self {
            publisher: dp
                .create_publisher(&qos)
                .map_err(|e| err(format!("{e:?}")))?,
            subscriber: dp
                .create_subscriber(&qos)
                .map_err(|e| err(format!("{e:?}")))?,
            dp,
            accept,
        })
    }

    /// The service `name` (absolute, `/wmr/arm`) of type `package/srv/ty`.
    pub fn service<Q, S>(
        &self,
        name: &str,
        package: &str,
        ty: &str,
    ) -> Result<Service<Q, S>, CreateError> {
        let qos: QosPolicies = (&topics::service_qos()).into();
        let err = |e: String| CreateError {
            name: name.to_string(),
            reason: e,
        };
        let rq = self
            .dp
            .create_topic(
                format!("rq{name}Request"),
                format!("{package}::srv::dds_::{ty}_Request_"),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(|e| err(format!("{e:?}")))?;
        let rr = self
            .dp
            .create_topic(
                format!("rr{name}Reply"),
                format!("{package}::srv::dds_::{ty}_Response_"),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(|e| err(format!("{e:?}")))?;
        let reader = self
            .subscriber
            .create_simple_datareader_no_key::<RawRequest, RawAdapter>(&rq, Some(qos.clone()))
            .map_err(|e| err(format!("{e:?}")))?;
        let writer = self
            .publisher
            .create_datawriter_no_key::<RawReply, RawAdapter>(&rr, Some(qos))
            .map_err(|e| err(format!("{e:?}")))?;
        Ok(Service {
            name: name.to_string(),
            accept: self.accept,
            reader,
            writer,
            refused: 0,
            phantom: PhantomData,
        })
    }
}

fn sample_id(s: &SampleIdentity) -> SampleId {
    SampleId {
        guid: s.writer_guid.to_bytes(),
        seq: i64::from(s.sequence_number),
    }
}

/// One service: requests of type `Q` in, responses `S` out.
pub struct Service<Q, S> {
    name: String,
    accept: Accept,
    reader: SimpleDataReader<RawRequest, RawAdapter>,
    writer: DataWriter<RawReply, RawAdapter>,
    /// Requests refused (not answerable in their caller's mapping, or not
    /// of this type).
    pub refused: u64,
    phantom: PhantomData<(Q, S)>,
}

/// A request that was refused, not acted on, with why.
pub struct Refused {
    /// The service.
    pub service: String,
    /// Why.
    pub reason: Unanswerable,
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.service, self.reason)
    }
}

impl<Q: DeserializeOwned, S: Serialize> Service<Q, S> {
    /// The service's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The next request and how to answer it; `Some(Err)` for one that
    /// cannot be answered (it must not be acted on).
    pub fn take(&mut self) -> Option<Result<(Call, Q), Refused>> {
        self.reader.drain_read_notifications();
        let dcc = match self.reader.try_take_one() {
            Ok(Some(d)) => d,
            _ => return None,
        };
        let related = dcc.related_sample_identity().map(|s| sample_id(&s));
        let sample = SampleId {
            guid: dcc.writer_guid().to_bytes(),
            seq: i64::from(dcc.sequence_number),
        };
        let raw = dcc.into_value();
        let inc = Incoming {
            payload: &raw.bytes,
            little_endian: matches!(
                raw.rep,
                RepresentationIdentifier::CDR_LE | RepresentationIdentifier::PL_CDR_LE
            ),
            sample,
            related,
        };
        let r = rpc::classify(&inc, self.accept).and_then(|call| {
            let q = rpc::decode::<Q>(&inc, &call)?;
            Ok((call, q))
        });
        Some(r.map_err(|reason| {
            self.refused += 1;
            Refused {
                service: self.name.clone(),
                reason,
            }
        }))
    }

    /// Answers `call` with `response`; false when DDS did not take it.
    pub fn reply(&self, call: &Call, response: &S) -> bool {
        let payload = rpc::reply_payload(call, response);
        let related = SampleIdentity {
            writer_guid: GUID::from_bytes(call.reply_related.guid),
            sequence_number: SequenceNumber::from(call.reply_related.seq),
        };
        let opts = WriteOptionsBuilder::new()
            .source_timestamp(Timestamp::now())
            .related_sample_identity(related)
            .build();
        self.writer
            .write_with_options(RawReply(Bytes::from(payload)), opts)
            .is_ok()
    }
}
