//! The robot on the link: the robot file it runs, read from its store
//! (protocol 4), and what the host takes from it that the handshake does
//! not carry — the centre-of-mass offset d of `base_link` (`/odom`, the
//! MCAP log) and the board's PWM timer clock.

use crate::link::{Link, LinkError};
use robot_file::Robot;
use wmr_protocol::{Reply, Request, CAP_ROBOT_STORE, ROBOT_BLOB_MAX, ROBOT_CHUNK};

/// The record's own CRC-32 (its last four bytes).
pub fn record_crc32(record: &[u8]) -> u32 {
    let n = record.len();
    if n < 4 {
        return 0;
    }
    u32::from_le_bytes([record[n - 4], record[n - 3], record[n - 2], record[n - 1]])
}

/// Whether the robot has a robot store (`CAP_ROBOT_STORE`).
pub fn has_store(link: &mut Link) -> Result<bool, LinkError> {
    Ok(super::hello(link)?.capabilities & CAP_ROBOT_STORE != 0)
}

/// The stored record read chunk by chunk (`Request::RobotRead`): the one
/// place that checks the robot's `RobotData` answers, for
/// [`read_record`] over a link and for `wmr serve`'s own requests.
#[derive(Debug, Default)]
pub struct RecordRead {
    record: Vec<u8>,
}

/// What [`RecordRead::accept`] leaves to do.
#[derive(Debug, PartialEq)]
pub enum RecordStep {
    /// Ask for the next chunk.
    Ask(Request),
    /// The whole record.
    Done(Vec<u8>),
}

/// Why a record could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RecordReadError {
    /// The answer was not the chunk asked for (or a record longer than
    /// `ROBOT_BLOB_MAX`).
    #[error("the robot answered {0} to a RobotRead")]
    Unexpected(String),
    /// A chunk came back empty before the record's end.
    #[error("the robot's record did not end")]
    NoEnd,
}

impl RecordRead {
    /// The first request.
    pub fn first() -> Request {
        Request::RobotRead { offset: 0 }
    }

    /// Takes the answer to the last request: the next request or the
    /// whole record. Every chunk but the last is non-empty, so a record of
    /// at most `ROBOT_BLOB_MAX` bytes ends within that many answers.
    pub fn accept(&mut self, reply: Reply) -> Result<RecordStep, RecordReadError> {
        let rec = &mut self.record;
        match reply {
            Reply::RobotData {
                total_len,
                offset,
                data,
                ..
            } if offset as usize == rec.len() && total_len as usize <= ROBOT_BLOB_MAX => {
                rec.extend_from_slice(&data);
                let total = total_len as usize;
                if rec.len() >= total {
                    rec.truncate(total);
                    Ok(RecordStep::Done(std::mem::take(rec)))
                } else if data.is_empty() {
                    Err(RecordReadError::NoEnd)
                } else {
                    Ok(RecordStep::Ask(Request::RobotRead {
                        offset: rec.len() as u16,
                    }))
                }
            }
            r => Err(RecordReadError::Unexpected(format!("{r:?}"))),
        }
    }
}

/// Reads the stored record.
pub fn read_record(link: &mut Link) -> Result<Vec<u8>, LinkError> {
    if !has_store(link)? {
        return Err(LinkError::Io(
            "this robot has no robot store (protocol 4 CAP_ROBOT_STORE)".into(),
        ));
    }
    let mut read = RecordRead::default();
    let mut req = RecordRead::first();
    for _ in 0..=ROBOT_BLOB_MAX / ROBOT_CHUNK + 1 {
        match read.accept(link.command(&req)?) {
            Ok(RecordStep::Ask(next)) => req = next,
            Ok(RecordStep::Done(rec)) => return Ok(rec),
            Err(RecordReadError::Unexpected(r)) => return Err(LinkError::Unexpected(r)),
            Err(e @ RecordReadError::NoEnd) => return Err(LinkError::Io(e.to_string())),
        }
    }
    Err(LinkError::Io(RecordReadError::NoEnd.to_string()))
}

/// Why the robot in force is not known.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NotKnown {
    /// No robot store: the firmware's compiled-in robot is not readable.
    #[error("the robot has no robot store (its compiled-in robot is not readable over the link)")]
    NoStore,
    /// A record was stored but the robot has not rebooted into it.
    #[error(
        "the robot's stored record (CRC-32 {stored:08x}) is not the one in force ({active:08x}): \
         it runs after a reboot (`wmr robot push` reboots)"
    )]
    NotInForce {
        /// CRC-32 of the stored record.
        stored: u32,
        /// CRC-32 of the record in force.
        active: u32,
    },
    /// The stored record does not decode.
    #[error("the robot's record does not decode: {0}")]
    Undecodable(String),
    /// The stored record could not be read (a refusal, no answer).
    #[error("the robot's record could not be read: {0}")]
    Unread(String),
}

/// The robot file the robot runs: its stored record when that is the
/// record in force (the status's `active_crc32`); `Ok(Err(why))` when the
/// robot cannot tell.
pub fn robot_in_force(link: &mut Link) -> Result<Result<Robot, NotKnown>, LinkError> {
    if !has_store(link)? {
        return Ok(Err(NotKnown::NoStore));
    }
    let active = super::status(link)?.robot.active_crc32;
    let rec = read_record(link)?;
    Ok(robot_of_record(&rec, active))
}

/// The robot file a stored record holds when it is the record in force
/// (`active_crc32`, a status's).
pub fn robot_of_record(rec: &[u8], active_crc32: u32) -> Result<Robot, NotKnown> {
    let stored = record_crc32(rec);
    if stored != active_crc32 {
        return Err(NotKnown::NotInForce {
            stored,
            active: active_crc32,
        });
    }
    Robot::decode(rec).map_err(|e| NotKnown::Undecodable(e.to_string()))
}

/// Where the d in use came from.
#[derive(Clone, Debug, PartialEq)]
pub enum ComOffsetSource {
    /// Given by the user (`--com-offset-m`).
    Given,
    /// The robot file the robot runs (`body.com_offset_m`), by name.
    Robot(String),
    /// The paper robot's, because the robot could not tell (why).
    PaperDefault(NotKnown),
}

/// d, G ahead of the axle midpoint \[m\], and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct ComOffset {
    /// d \[m\].
    pub com_offset_m: f64,
    /// Its source.
    pub source: ComOffsetSource,
}

impl std::fmt::Display for ComOffset {
    /// `d = 0.005 m (robot "x"'s body.com_offset_m)` and the like.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // As the f32 the robot file holds (0.02, not 0.019999999552965164).
        let d = self.com_offset_m as f32;
        match &self.source {
            ComOffsetSource::Given => write!(f, "d = {d} m (--com-offset-m)"),
            ComOffsetSource::Robot(n) => {
                write!(
                    f,
                    "d = {d} m (body.com_offset_m of robot \"{n}\" on the link)"
                )
            }
            ComOffsetSource::PaperDefault(why) => write!(
                f,
                "d = {d} m, the paper robot's: {why}; give --com-offset-m for another robot"
            ),
        }
    }
}

/// d for `base_link`: `given` when the user gave it, else the robot's own
/// (`body.com_offset_m` of [`robot_in_force`]), else the paper robot's
/// (the reason in the source).
pub fn com_offset_m(link: &mut Link, given: Option<f64>) -> Result<ComOffset, LinkError> {
    if let Some(d) = given {
        return Ok(ComOffset::given(d));
    }
    Ok(ComOffset::of_robot(robot_in_force(link)?))
}

impl ComOffset {
    /// d as the user gave it (`--com-offset-m`).
    pub fn given(d: f64) -> Self {
        Self {
            com_offset_m: d,
            source: ComOffsetSource::Given,
        }
    }

    /// d of the robot in force, else the paper robot's with the reason.
    pub fn of_robot(robot: Result<Robot, NotKnown>) -> Self {
        match robot {
            Ok(r) => Self {
                com_offset_m: r.body.com_offset_m as f64,
                source: ComOffsetSource::Robot(r.name.as_str().to_string()),
            },
            Err(why) => Self {
                com_offset_m: ros_mcap::default_com_offset_m(),
                source: ComOffsetSource::PaperDefault(why),
            },
        }
    }
}

/// The PWM timer clock \[Hz\] of the board a handshake names (`chip`):
/// the firmware's `TIM1_CLOCK_HZ` for each chip feature and the simulated
/// device's `SIM_TIMER_CLOCK_HZ`, each one of robot-file's
/// `SUPPORTED_TIMER_CLOCKS_HZ`. `None` for a board wmr does not know.
pub fn timer_clock_of_chip(chip: &str) -> Option<u32> {
    let [f411, f405] = robot_file::SUPPORTED_TIMER_CLOCKS_HZ;
    match chip {
        // F411: APB2 96 MHz, timers ×1.
        "stm32f411ce" => Some(f411),
        // F446 at SYSCLK 168 MHz: APB2 84 MHz, timers ×2.
        "stm32f446re" => Some(f405),
        // hil-sim's device runs the F411's timer.
        "sim" => Some(f411),
        _ => None,
    }
}
