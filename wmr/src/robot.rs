//! `wmr robot push|pull|diff|check`: the robot file in the robot's flash
//! (protocol 4, book/src/reference/protocol.md "The robot record").

use crate::link::{Link, LinkError};
use crate::session::{has_store, status};
pub use crate::session::{read_record, record_crc32};
use clap::{Args, Subcommand};
use robot_file::Robot;
use std::io::Write;
use std::path::Path;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wmr_protocol::{Reply, Request, RobotFault, RobotSource, ROBOT_BLOB_MAX, ROBOT_CHUNK};

/// `robot` options.
#[derive(Debug, Args)]
pub struct RobotArgs {
    /// push, pull, diff or check.
    #[command(subcommand)]
    pub op: RobotOp,
}

/// `robot` operations.
#[derive(Debug, Subcommand)]
pub enum RobotOp {
    /// Validate FILE locally, store it in the robot's flash (hold only),
    /// read it back and compare, then reboot the robot into it.
    Push {
        /// Robot file (TOML, book/src/how-to/robot-file.md).
        file: PathBuf,
        /// Store only: the robot runs it from its next boot.
        #[arg(long)]
        no_reboot: bool,
        /// Skip the local validation (to see the robot's own refusal).
        #[arg(long, hide = true)]
        no_local_check: bool,
    },
    /// Read the robot's stored record and print it as a robot file.
    Pull {
        /// Write it to this file instead of stdout.
        #[arg(short = 'o', long = "out")]
        out: Option<PathBuf>,
    },
    /// Field-by-field differences between FILE and the robot's record.
    Diff {
        /// Robot file (TOML).
        file: PathBuf,
    },
    /// Validate FILE offline (no robot needed) and print derived values.
    Check {
        /// Robot file (TOML).
        file: PathBuf,
    },
}

/// Runs one `robot` operation (`check` needs no link: [`check`]).
pub fn robot(op: &RobotOp, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    match op {
        RobotOp::Push {
            file,
            no_reboot,
            no_local_check,
        } => push(link, file, !no_local_check, *no_reboot, out),
        RobotOp::Pull { out: file } => pull(link, file.as_deref(), out),
        RobotOp::Diff { file } => diff(link, file, out),
        RobotOp::Check { file } => check(file, out),
    }
}

/// How long `push` waits for the robot's answer to the commit (the flash
/// write: an F4 sector erase takes up to 2 s at 3.3 V, 4 s at x8
/// parallelism; the firmware's stretched watchdog allows 8 s).
pub const COMMIT_WAIT: Duration = Duration::from_secs(15);
/// How long `push` waits for the robot to answer again after `Reboot`.
pub const REBOOT_WAIT: Duration = Duration::from_secs(10);

fn err(s: impl Into<String>) -> LinkError {
    LinkError::Io(s.into())
}

/// Reads and validates a robot file (errors name the field and line).
pub fn read_file(path: &Path) -> Result<Robot, LinkError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| err(format!("cannot read {}: {e}", path.display())))?;
    Robot::from_toml_str(&text).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// Reads a robot file without validating it (`push --no-local-check`: to
/// see the robot's own refusal).
fn read_unchecked(path: &Path) -> Result<Robot, LinkError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| err(format!("cannot read {}: {e}", path.display())))?;
    toml::from_str(&text).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// The robot's binary form.
pub fn encode(robot: &Robot) -> Result<Vec<u8>, LinkError> {
    let mut buf = [0u8; ROBOT_BLOB_MAX];
    let n = robot
        .encode(&mut buf)
        .map_err(|e| err(format!("cannot encode the robot: {e}")))?;
    Ok(buf[..n].to_vec())
}

/// A refusal from the robot as one line.
pub fn fault_line(f: &RobotFault) -> String {
    let mut s = String::from("the robot refused the record: ");
    if !f.field.is_empty() {
        s += &format!("{}: ", f.field);
    }
    s += f.kind.reason();
    if let Some([lo, hi]) = f.range {
        s += &format!(" [{lo}, {hi}]");
    }
    s
}

/// `wmr robot check FILE`: offline validation and the derived values.
pub fn check(path: &Path, out: &mut dyn Write) -> Result<(), LinkError> {
    let r = read_file(path)?;
    let rec = encode(&r)?;
    let io = |e: std::io::Error| err(e.to_string());
    writeln!(out, "{}: valid robot \"{}\"", path.display(), r.name).map_err(io)?;
    writeln!(
        out,
        "binary form: {} bytes (max {ROBOT_BLOB_MAX}), CRC-32 {:08x}",
        rec.len(),
        record_crc32(&rec)
    )
    .map_err(io)?;
    let period_s = robot_file::CONTROL_PERIOD_S;
    let w = r.no_load_wheel_speed_radps();
    writeln!(
        out,
        "mean wheel radius {:.4} m, stall torque at the wheel {:.3} N·m, no-load wheel speed {:.1} rad/s ({:.2} m/s)",
        r.mean_wheel_radius_m(),
        r.stall_torque_nm(),
        w,
        r.no_load_speed_mps()
    )
    .map_err(io)?;
    writeln!(
        out,
        "encoder: {:.1} counts per {:.0} ms tick at the no-load speed",
        r.counts_per_tick(w, period_s),
        period_s * 1e3
    )
    .map_err(io)?;
    let s = r.safety_limits(period_s);
    writeln!(
        out,
        "safety: stall check {:.3} N·m for {} ticks, encoder jump limit {} counts/tick",
        s.stall_torque_nm, s.stall_ticks, s.max_counts_per_tick
    )
    .map_err(io)?;
    Ok(())
}

/// Uploads and commits `rec`; returns when the robot has written it.
fn write_record(link: &mut Link, rec: &[u8]) -> Result<(), LinkError> {
    if !has_store(link)? {
        return Err(err(
            "this robot has no robot store (protocol 4 CAP_ROBOT_STORE)",
        ));
    }
    link.command(&Request::RobotBegin {
        total_len: rec.len() as u16,
    })?;
    for (k, c) in rec.chunks(ROBOT_CHUNK).enumerate() {
        link.command(&Request::RobotChunk {
            offset: (k * ROBOT_CHUNK) as u16,
            data: c.iter().copied().collect(),
        })?;
    }
    // Sent once: the answer comes when the flash write ends (seconds).
    let seq = link.send(&Request::RobotCommit)?;
    let end = Instant::now() + COMMIT_WAIT;
    while Instant::now() < end {
        for (s, r) in link.receive(Duration::from_millis(50))? {
            if s != seq {
                continue;
            }
            return match r {
                Reply::Ack { .. } => Ok(()),
                Reply::RobotRejected { fault, .. } => Err(err(fault_line(&fault))),
                Reply::Nack { error, .. } => Err(LinkError::Nack("RobotCommit".into(), error)),
                r => Err(LinkError::Unexpected(format!("{r:?}"))),
            };
        }
    }
    Err(LinkError::NoAnswer(format!(
        "RobotCommit within {} s",
        COMMIT_WAIT.as_secs()
    )))
}

/// Asks the robot to reboot and waits until it answers a handshake again.
fn reboot(link: &mut Link) -> Result<(), LinkError> {
    link.command(&Request::Reboot)?;
    let end = Instant::now() + REBOOT_WAIT;
    loop {
        std::thread::sleep(Duration::from_millis(100));
        match link.hello() {
            Ok(_) => return Ok(()),
            Err(e) if Instant::now() >= end => {
                return Err(err(format!(
                    "the robot did not come back after the reboot: {e}"
                )))
            }
            Err(_) => {}
        }
    }
}

/// `wmr robot push FILE`: validates locally (unless `check_locally` is
/// false), writes, reads back and compares; then reboots into it (unless
/// `no_reboot`) and checks the robot runs it.
pub fn push(
    link: &mut Link,
    path: &Path,
    check_locally: bool,
    no_reboot: bool,
    out: &mut dyn Write,
) -> Result<(), LinkError> {
    let robot = if check_locally {
        read_file(path)?
    } else {
        read_unchecked(path)?
    };
    let rec = encode(&robot)?;
    let io = |e: std::io::Error| err(e.to_string());
    let crc = record_crc32(&rec);
    // A failure on the way (a lost answer, a cut line) may come after the
    // robot stored the record, or before: ask it what it stores and runs
    // now, and say so with the error (issue 31 item 5).
    let truthfully = |link: &mut Link, e: LinkError| -> LinkError {
        // `err` adds the link-error prefix once.
        let e = match e {
            LinkError::Io(m) => m,
            other => other.to_string(),
        };
        match status(link) {
            Ok(s) => {
                let r = s.robot;
                let stored = if r.stored_crc32 == crc {
                    "the pushed record"
                } else {
                    "not the pushed record"
                };
                let runs = if r.active_crc32 == crc {
                    "the pushed record"
                } else {
                    "not the pushed record"
                };
                err(format!(
                    "{e}; the robot now stores CRC-32 {:08x} ({stored}) and runs CRC-32 {:08x} \
                     from {:?} ({runs}; pushed: {crc:08x})",
                    r.stored_crc32, r.active_crc32, r.source
                ))
            }
            Err(s) => err(format!(
                "{e}; the robot did not answer a status request either ({s}): what it stores \
                 is unknown, check with `wmr status` when it answers"
            )),
        }
    };
    if let Err(e) = write_record(link, &rec) {
        return Err(truthfully(link, e));
    }
    let back = match read_record(link) {
        Ok(b) => b,
        Err(e) => return Err(truthfully(link, e)),
    };
    if back != rec {
        return Err(err(format!(
            "read back differs from what was written ({} vs {} bytes)",
            back.len(),
            rec.len()
        )));
    }
    writeln!(
        out,
        "stored \"{}\" ({} bytes, CRC-32 {:08x}), read back equal",
        robot.name,
        rec.len(),
        record_crc32(&rec)
    )
    .map_err(io)?;
    if no_reboot {
        writeln!(out, "takes effect at the robot's next boot (`wmr robot push` without --no-reboot reboots it)").map_err(io)?;
        return Ok(());
    }
    if let Err(e) = reboot(link) {
        return Err(truthfully(link, e));
    }
    let s = status(link)?;
    if s.robot.source != RobotSource::Flash || s.robot.active_crc32 != record_crc32(&rec) {
        return Err(err(format!(
            "after the reboot the robot runs {:?} (CRC-32 {:08x}), not the pushed record",
            s.robot.source, s.robot.active_crc32
        )));
    }
    writeln!(
        out,
        "rebooted: the robot runs \"{}\" from flash",
        robot.name
    )
    .map_err(io)?;
    Ok(())
}

/// `wmr robot pull [-o FILE]`: the stored record as a robot file.
pub fn pull(
    link: &mut Link,
    out_file: Option<&Path>,
    out: &mut dyn Write,
) -> Result<(), LinkError> {
    let rec = read_record(link)?;
    let robot = Robot::decode(&rec).map_err(|e| err(format!("the robot's record: {e}")))?;
    let text = robot.to_toml_string();
    match out_file {
        Some(p) => {
            std::fs::write(p, &text)
                .map_err(|e| err(format!("cannot write {}: {e}", p.display())))?;
            writeln!(out, "wrote \"{}\" to {}", robot.name, p.display())
                .map_err(|e| err(e.to_string()))?;
        }
        None => out
            .write_all(text.as_bytes())
            .map_err(|e| err(e.to_string()))?,
    }
    Ok(())
}

fn flatten(prefix: &str, v: &toml::Value, out: &mut Vec<(String, String)>) {
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                let p = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&p, x, out);
            }
        }
        toml::Value::Array(a) if a.iter().all(|x| !x.is_table()) => {
            for (i, x) in a.iter().enumerate() {
                flatten(&format!("{prefix}[{i}]"), x, out);
            }
        }
        other => out.push((prefix.to_string(), other.to_string())),
    }
}

/// Field-by-field differences `(path, a, b)` between two robots ("-" for
/// a field one of them lacks).
pub fn differences(a: &Robot, b: &Robot) -> Vec<(String, String, String)> {
    let flat = |r: &Robot| {
        let v: toml::Value = toml::from_str(&r.to_toml_string()).expect("a robot file is TOML");
        let mut f = Vec::new();
        flatten("", &v, &mut f);
        f
    };
    let (fa, fb) = (flat(a), flat(b));
    let get = |f: &[(String, String)], k: &str| f.iter().find(|(p, _)| p == k).map(|x| x.1.clone());
    let mut keys: Vec<String> = fa.iter().chain(fb.iter()).map(|x| x.0.clone()).collect();
    keys.dedup();
    let mut seen = std::collections::HashSet::new();
    keys.retain(|k| seen.insert(k.clone()));
    keys.into_iter()
        .filter_map(|k| {
            let (x, y) = (get(&fa, &k), get(&fb, &k));
            (x != y).then(|| {
                let d = |v: Option<String>| v.unwrap_or_else(|| "-".into());
                (k, d(x), d(y))
            })
        })
        .collect()
}

/// `wmr robot diff FILE`: the file against the robot's stored record.
/// Differences are printed; they are not an error.
pub fn diff(link: &mut Link, path: &Path, out: &mut dyn Write) -> Result<(), LinkError> {
    let local = read_file(path)?;
    let rec = read_record(link)?;
    let remote = Robot::decode(&rec).map_err(|e| err(format!("the robot's record: {e}")))?;
    let io = |e: std::io::Error| err(e.to_string());
    let d = differences(&local, &remote);
    if d.is_empty() {
        writeln!(
            out,
            "{} and the robot's record are the same robot",
            path.display()
        )
        .map_err(io)?;
    }
    for (k, a, b) in d {
        writeln!(out, "{k}: file {a}, robot {b}").map_err(io)?;
    }
    Ok(())
}
