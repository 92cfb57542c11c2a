//! Reading a log back: every message with its topic and time, and the
//! trace rows of `/wmr/tracking` for the metrics.

use crate::msg::{self, Tracking};
use crate::{LogError, TraceSample};
use wmr_protocol::RunStateMsg;

/// The 8 bytes an MCAP file starts with.
const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// One message of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct LoggedMessage {
    /// Topic.
    pub topic: String,
    /// Schema name (`pkg/msg/Type`).
    pub schema: String,
    /// Log time \[ns\].
    pub log_time_ns: u64,
    /// The CDR bytes (with the encapsulation header).
    pub data: Vec<u8>,
}

/// True when `bytes` start as an MCAP file does.
pub fn is_mcap(bytes: &[u8]) -> bool {
    bytes.starts_with(MAGIC)
}

/// Every message of the MCAP file `bytes`, in file order.
pub fn read_messages(bytes: &[u8]) -> Result<Vec<LoggedMessage>, LogError> {
    if !is_mcap(bytes) {
        return Err(LogError::Mcap("not an MCAP file (no magic bytes)".into()));
    }
    let stream = mcap::MessageStream::new(bytes).map_err(|e| LogError::Mcap(e.to_string()))?;
    let mut out = Vec::new();
    for m in stream {
        let m = m.map_err(|e| LogError::Mcap(e.to_string()))?;
        out.push(LoggedMessage {
            topic: m.channel.topic.clone(),
            schema: m
                .channel
                .schema
                .as_ref()
                .map_or_else(String::new, |s| s.name.clone()),
            log_time_ns: m.log_time,
            data: m.data.into_owned(),
        });
    }
    Ok(out)
}

/// The trace row of a `/wmr/tracking` message.
pub fn sample_of_tracking(t: &Tracking) -> TraceSample {
    TraceSample {
        t_s: t.t_s,
        ref_pose: t.ref_pose,
        pose: t.pose,
        pos_err_m: t.pos_err_m,
        err_xy_m: t.err_xy_m,
        e: t.e,
        eta: t.eta,
        eta_c: t.eta_c,
        torque_nm: t.torque_nm,
        s: t.s,
        rho_hat: t.rho_hat,
        d_hat: t.d_hat,
        f_hat: t.f_hat,
        f_true: t.f_true,
        saturated: t.saturated,
        time_scale: t.time_scale,
        tau_s: t.tau_s,
        health: t.health,
        health_reason: t.health_reason,
    }
}

/// The rows of the trace CSV of the same run: `/wmr/tracking` messages
/// while running or stopping (the CSV's rows), in order.
pub fn read_trace(bytes: &[u8]) -> Result<Vec<TraceSample>, LogError> {
    let running = RunStateMsg::Running as u8;
    let stopping = RunStateMsg::Stopping as u8;
    let mut out = Vec::new();
    for m in read_messages(bytes)? {
        if m.topic != crate::TOPIC_TRACKING {
            continue;
        }
        let t: Tracking = msg::decode(&m.data).map_err(LogError::Cdr)?;
        if t.state == running || t.state == stopping {
            out.push(sample_of_tracking(&t));
        }
    }
    Ok(out)
}

/// The trace of a log file, MCAP or CSV (told by its first bytes).
pub fn read_log(path: &std::path::Path) -> Result<Vec<TraceSample>, LogError> {
    let bytes = std::fs::read(path)
        .map_err(|e| LogError::Io(format!("cannot read {}: {e}", path.display())))?;
    if is_mcap(&bytes) {
        read_trace(&bytes).map_err(|e| LogError::Io(format!("{}: {e}", path.display())))
    } else {
        track_log::csv::read_trace_csv(&bytes[..], &path.display().to_string())
            .map_err(LogError::Io)
    }
}
