//! `wmr serve --live`: the robot's telemetry as the MCAP logs' topics on a
//! Foxglove WebSocket server (ros-mcap's `LiveView`). The view starts once
//! the robot's geometry is known: r and h from its hello (`RobotInfo`), d
//! as `wmr record --mcap` takes it ([`crate::session::com_offset_m`]):
//! `--com-offset-m` when given, else `body.com_offset_m` of the robot file
//! the robot runs (its stored record when that is the record in force,
//! read through the server's own requests), else the paper robot's with
//! the reason logged. Stamps are host Unix time mapped from the first
//! frame's arrival.

use crate::session::{robot_of_record, ComOffset, NotKnown, RecordRead, RecordStep};
use ros_mcap::live::{LiveArgs, LiveView};
use ros_mcap::{Geometry, LogFrame, TimeMap};
use std::time::{Duration, Instant};
use wmr_protocol::{Reply, Request, RobotInfo, Telemetry, CAP_ROBOT_STORE};

/// How long the view waits for the robot's record before it starts with
/// the paper robot's d (the server's own requests are re-sent 3 times at
/// 25 ms or more: an answer lost past that never comes).
pub(crate) const RECORD_WAIT: Duration = Duration::from_secs(2);

/// What the server does next for the view.
#[derive(Debug, PartialEq)]
pub(crate) enum LiveStep {
    /// Nothing.
    None,
    /// Send this request as the server's own (`Own::RobotRead`).
    Ask(Request),
    /// A line for the server's log.
    Log(String),
}

/// Reading the robot's record for d.
struct Reading {
    /// r and h from the hello.
    wheel_radius_m: f64,
    half_track_m: f64,
    /// The chunks so far.
    read: RecordRead,
    /// The whole record, once read.
    record: Option<Vec<u8>>,
    /// The record in force (a status's `active_crc32`).
    active_crc32: Option<u32>,
    /// Start with the paper robot's d after this.
    deadline: Instant,
}

/// The live view of a server.
pub(crate) struct ServeLive {
    at: LiveArgs,
    /// d given by the user.
    given_com_offset_m: Option<f64>,
    view: Option<LiveView>,
    /// The d the view started with.
    started_with: Option<ComOffset>,
    reading: Option<Reading>,
    time_map: Option<TimeMap>,
}

impl ServeLive {
    /// A view to start on `at`'s address once the robot is known, with
    /// d `given_com_offset_m` when the user gave it.
    pub fn new(at: LiveArgs, given_com_offset_m: Option<f64>) -> Self {
        Self {
            at,
            given_com_offset_m,
            view: None,
            started_with: None,
            reading: None,
            time_map: None,
        }
    }

    /// The robot answered its hello: starts the view at once when d is
    /// given or the robot has no store, else asks for its record.
    pub fn on_hello(&mut self, hello: &Reply, now: Instant) -> LiveStep {
        if self.started_with.is_some() || self.reading.is_some() {
            return LiveStep::None;
        }
        let Reply::Hello {
            robot,
            capabilities,
            ..
        } = hello
        else {
            return LiveStep::None;
        };
        let RobotInfo {
            wheel_radius_m,
            half_track_m,
            ..
        } = *robot;
        let (r, h) = (wheel_radius_m as f64, half_track_m as f64);
        if let Some(d) = self.given_com_offset_m {
            return self.start(r, h, ComOffset::given(d));
        }
        if capabilities & CAP_ROBOT_STORE == 0 {
            return self.start(r, h, ComOffset::of_robot(Err(NotKnown::NoStore)));
        }
        self.reading = Some(Reading {
            wheel_radius_m: r,
            half_track_m: h,
            read: RecordRead::default(),
            record: None,
            active_crc32: None,
            deadline: now + RECORD_WAIT,
        });
        LiveStep::Ask(RecordRead::first())
    }

    /// A status from the robot: the record in force.
    pub fn on_status(&mut self, active_crc32: u32) -> LiveStep {
        match &mut self.reading {
            Some(rd) => {
                rd.active_crc32 = Some(active_crc32);
                self.finish()
            }
            None => LiveStep::None,
        }
    }

    /// The answer to the view's `RobotRead`.
    pub fn on_record(&mut self, reply: Reply) -> LiveStep {
        let Some(rd) = &mut self.reading else {
            return LiveStep::None;
        };
        match rd.read.accept(reply) {
            Ok(RecordStep::Ask(req)) => LiveStep::Ask(req),
            Ok(RecordStep::Done(rec)) => {
                rd.record = Some(rec);
                self.finish()
            }
            Err(e) => self.give_up(NotKnown::Unread(e.to_string())),
        }
    }

    /// The wait for the record ran out: the paper robot's d.
    pub fn poll(&mut self, now: Instant) -> LiveStep {
        match &self.reading {
            Some(rd) if now >= rd.deadline => self.give_up(NotKnown::Unread(format!(
                "no answer within {} s",
                RECORD_WAIT.as_secs_f64()
            ))),
            _ => LiveStep::None,
        }
    }

    /// Starts the view when the record and the record in force are both
    /// known.
    fn finish(&mut self) -> LiveStep {
        let Some(rd) = &self.reading else {
            return LiveStep::None;
        };
        let (Some(rec), Some(active)) = (&rd.record, rd.active_crc32) else {
            return LiveStep::None;
        };
        let d = ComOffset::of_robot(robot_of_record(rec, active));
        let (r, h) = (rd.wheel_radius_m, rd.half_track_m);
        self.start(r, h, d)
    }

    fn give_up(&mut self, why: NotKnown) -> LiveStep {
        match self.reading.as_ref() {
            Some(rd) => {
                let (r, h) = (rd.wheel_radius_m, rd.half_track_m);
                self.start(r, h, ComOffset::of_robot(Err(why)))
            }
            None => LiveStep::None,
        }
    }

    fn start(&mut self, r: f64, h: f64, d: ComOffset) -> LiveStep {
        self.reading = None;
        let started = Geometry::new(r, h, d.com_offset_m)
            .map_err(|e| e.to_string())
            .and_then(|g| self.at.start(g, "wmr serve").map_err(|e| e.to_string()));
        let line = match started {
            Ok(v) => {
                let line = format!("live view: {} ({d})", self.at.url(v.port()));
                self.view = Some(v);
                line
            }
            Err(e) => e,
        };
        self.started_with = Some(d);
        LiveStep::Log(line)
    }

    /// The d the view started with, and its source.
    #[cfg(test)]
    fn com_offset(&self) -> Option<&ComOffset> {
        self.started_with.as_ref()
    }

    /// A telemetry frame from the robot: published when it has the
    /// tracking group.
    pub fn telemetry(&mut self, t: &Telemetry) -> Result<(), String> {
        let Some(v) = &mut self.view else {
            return Ok(());
        };
        let map = self
            .time_map
            .get_or_insert_with(|| TimeMap::new(t.t_robot_us, ros_mcap::unix_now_ns()));
        let stamp = map.host_ns(t.t_robot_us);
        match LogFrame::of_telemetry(t, stamp, None) {
            Some(f) => v.publish(&f).map_err(|e| format!("live view: {e}")),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::{record_crc32, ComOffsetSource};
    use robot_file::Robot;
    use wmr_protocol::ROBOT_CHUNK;

    fn hello(capabilities: u16) -> Reply {
        Reply::Hello {
            seq: 1,
            version: wmr_protocol::PROTOCOL_VERSION,
            capabilities,
            chip: heapless::String::try_from("sim").unwrap(),
            robot: RobotInfo {
                wheel_radius_m: 0.033,
                half_track_m: 0.08,
                mass_kg: 2.0,
                control_period_s: 1e-3,
                torque_limit_nm: 0.25,
            },
        }
    }

    fn live(given: Option<f64>) -> ServeLive {
        ServeLive::new(
            LiveArgs {
                live_host: "127.0.0.1".into(),
                live_port: 0,
            },
            given,
        )
    }

    fn tb6612() -> (Robot, Vec<u8>) {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../robots/tb6612-2kg.toml"
        ))
        .unwrap();
        let r = Robot::from_toml_str(&text).unwrap();
        let mut buf = [0u8; robot_file::MAX_ENCODED_LEN];
        let n = r.encode(&mut buf).unwrap();
        (r, buf[..n].to_vec())
    }

    /// Serves the record's chunks for the view's requests until it stops
    /// asking; the steps it took.
    fn feed(l: &mut ServeLive, first: LiveStep, rec: &[u8]) -> LiveStep {
        let mut step = first;
        while let LiveStep::Ask(Request::RobotRead { offset }) = step {
            let o = offset as usize;
            let end = (o + ROBOT_CHUNK).min(rec.len());
            step = l.on_record(Reply::RobotData {
                seq: 2,
                total_len: rec.len() as u16,
                offset,
                data: heapless::Vec::from_slice(&rec[o..end]).unwrap(),
            });
        }
        step
    }

    /// The view's d is the robot file's when its record is the one in
    /// force (the tb6612 robot's 0.02 m, not the paper's 0.05), in
    /// either order of the record and the status.
    #[test]
    fn the_view_takes_d_from_the_robot_in_force() {
        let (robot, rec) = tb6612();
        let d = robot.body.com_offset_m as f64;
        assert_ne!(d, ros_mcap::default_com_offset_m());
        let crc = record_crc32(&rec);
        // Record first, then the status.
        let mut l = live(None);
        let ask = l.on_hello(&hello(CAP_ROBOT_STORE), Instant::now());
        assert_eq!(ask, LiveStep::Ask(Request::RobotRead { offset: 0 }));
        assert_eq!(feed(&mut l, ask, &rec), LiveStep::None);
        assert!(l.com_offset().is_none(), "waits for the record in force");
        let LiveStep::Log(line) = l.on_status(crc) else {
            panic!("started")
        };
        let c = l.com_offset().unwrap();
        assert_eq!(c.com_offset_m, d);
        assert_eq!(c.source, ComOffsetSource::Robot(robot.name.as_str().into()));
        assert!(
            line.contains("ws://127.0.0.1:") && line.contains("tb6612"),
            "{line}"
        );
        // A second hello (a reconnect) does not start another view.
        assert_eq!(
            l.on_hello(&hello(CAP_ROBOT_STORE), Instant::now()),
            LiveStep::None
        );
        // The status first.
        let mut l = live(None);
        let ask = l.on_hello(&hello(CAP_ROBOT_STORE), Instant::now());
        assert_eq!(l.on_status(crc), LiveStep::None);
        assert!(matches!(feed(&mut l, ask, &rec), LiveStep::Log(_)));
        assert_eq!(l.com_offset().unwrap().com_offset_m, d);
    }

    /// Every way the robot cannot tell gives the paper robot's d and says
    /// why; a given d is used as given, without asking the robot.
    #[test]
    fn the_paper_d_only_with_its_reason() {
        let (_, rec) = tb6612();
        let paper_d = ros_mcap::default_com_offset_m();
        let now = Instant::now();
        // No store.
        let mut l = live(None);
        assert!(matches!(l.on_hello(&hello(0), now), LiveStep::Log(_)));
        let c = l.com_offset().unwrap();
        assert_eq!(c.com_offset_m, paper_d);
        assert_eq!(c.source, ComOffsetSource::PaperDefault(NotKnown::NoStore));
        // A stored record the robot has not rebooted into.
        let mut l = live(None);
        let ask = l.on_hello(&hello(CAP_ROBOT_STORE), now);
        feed(&mut l, ask, &rec);
        l.on_status(record_crc32(&rec) ^ 1);
        let c = l.com_offset().unwrap();
        assert!(
            matches!(
                c.source,
                ComOffsetSource::PaperDefault(NotKnown::NotInForce { .. })
            ),
            "{c:?}"
        );
        assert!(c.to_string().contains("give --com-offset-m"), "{c}");
        // A refusal.
        let mut l = live(None);
        l.on_hello(&hello(CAP_ROBOT_STORE), now);
        l.on_record(Reply::Nack {
            seq: 2,
            error: wmr_protocol::ErrorCode::Busy,
        });
        assert_eq!(l.com_offset().unwrap().com_offset_m, paper_d);
        // No answer within the wait.
        let mut l = live(None);
        l.on_hello(&hello(CAP_ROBOT_STORE), now);
        assert_eq!(l.poll(now + RECORD_WAIT / 2), LiveStep::None);
        assert!(matches!(l.poll(now + RECORD_WAIT), LiveStep::Log(_)));
        assert_eq!(l.com_offset().unwrap().com_offset_m, paper_d);
        // Given.
        let mut l = live(Some(0.012));
        assert!(matches!(
            l.on_hello(&hello(CAP_ROBOT_STORE), now),
            LiveStep::Log(_)
        ));
        let c = l.com_offset().unwrap();
        assert_eq!(
            (c.com_offset_m, &c.source),
            (0.012, &ComOffsetSource::Given)
        );
    }
}
