//! The server's routing, without any I/O: requests of many clients onto the
//! one link with sequence numbers of the server's own, answers back to the
//! client (and sequence number) that asked, telemetry to every client that
//! turned it on, events to every client, and the robot's telemetry setting
//! as the union of what the clients asked for (D96).

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::{Duration, Instant};
use wmr_protocol::{ParamId, Reply, Request, TelemetrySelection, TELEMETRY_ALL};

/// A connected client (numbered from 1 in connection order).
pub type ClientId = u64;

/// The id under which the server's own telemetry subscription is held.
pub const OWN_CLIENT: ClientId = 0;

/// How long an answer is waited for before its routing entry is dropped:
/// above the longest answer any command waits for (`RobotCommit`, a flash
/// write: `wmr` waits 15 s).
pub const PENDING_TTL: Duration = Duration::from_secs(30);

/// Telemetry groups and rate, as `Request::SetTelemetry` gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TelemetrySub {
    /// `TELEMETRY_*` bits.
    pub selection: TelemetrySelection,
    /// Frames per second (0 = off).
    pub rate_hz: u16,
}

impl TelemetrySub {
    /// Telemetry off (the canonical form: the groups do not matter).
    pub const OFF: Self = Self {
        selection: TELEMETRY_ALL,
        rate_hz: 0,
    };
}

/// Requests the server itself sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Own {
    /// The handshake after (re)connecting.
    Hello,
    /// A clock-sync keep-alive.
    KeepAlive,
    /// A periodic status (state, counters: reset detection).
    Status,
    /// The robot's link timeout.
    LinkTimeout,
    /// The telemetry setting (after a client left, after a reset).
    Telemetry,
    /// A chunk of the robot's record (the live view's d).
    RobotRead,
}

/// Who gets the answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A client's request with the client's own sequence number.
    Client {
        /// Which client.
        id: ClientId,
        /// Its sequence number.
        seq: u16,
    },
    /// The server's own.
    Own(Own),
}

/// What the server watches for in an answer.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Plain,
    /// The union telemetry setting; on a refusal the client's previous
    /// subscription comes back.
    Telemetry {
        sent: TelemetrySub,
        client_prev: Option<(ClientId, Option<TelemetrySub>)>,
    },
    /// `SetParam(LinkTimeoutMs)`: the server's timing follows it.
    LinkTimeout(f32),
    /// `Reboot`: the reset that follows is expected.
    Reboot,
    /// `WheelTest`: answered twice (ack, then `WheelTestDone`).
    WheelTest,
}

#[derive(Clone, Debug)]
struct Pending {
    origin: Origin,
    kind: Kind,
    at: Instant,
    /// The request, for re-sending (`None`: never re-sent).
    req: Option<Request>,
    last_sent: Instant,
    resends: u32,
}

/// One thing to do.
#[derive(Clone, Debug, PartialEq)]
pub enum Out {
    /// Send this request to the robot with this (server) sequence number.
    Robot(u16, Request),
    /// Send this reply to this client.
    Client(ClientId, Reply),
}

/// Something the server learns from an answer.
#[derive(Clone, Debug, PartialEq)]
pub enum Note {
    /// The answer to one of the server's own requests.
    Own(Own, Box<Reply>),
    /// The robot acknowledged a new link timeout \[ms\].
    LinkTimeoutSet(f32),
    /// The robot acknowledged a reboot request: the next reset is expected.
    RebootAcked,
}

/// Counters of the routing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct MuxCounters {
    /// Client requests sent on to the robot.
    pub forwarded: u64,
    /// Client requests the server answered itself (a telemetry setting
    /// the robot already has).
    pub answered_locally: u64,
    /// Answers routed back to a client.
    pub answers_routed: u64,
    /// Answers whose request was not (or no longer) known: a client gone,
    /// a retry's twin, an answer after [`PENDING_TTL`].
    pub unmatched: u64,
    /// Telemetry frames fanned out (one per frame and client).
    pub telemetry_out: u64,
    /// Events fanned out (one per event and client).
    pub events_out: u64,
    /// `Reply::FrameError` from the robot (a frame of ours it dropped).
    pub frame_errors: u64,
    /// Requests sent again under the same number after no answer (D96).
    pub resent: u64,
}

/// The routing state.
#[derive(Debug)]
pub struct Mux {
    next_seq: u16,
    pending: HashMap<u16, Pending>,
    clients: BTreeSet<ClientId>,
    subs: BTreeMap<ClientId, TelemetrySub>,
    /// What the robot acknowledged last (`None`: not known, after a reset
    /// or before the first).
    robot_tel: Option<TelemetrySub>,
    /// Counters.
    pub counters: MuxCounters,
}

impl Default for Mux {
    fn default() -> Self {
        Self::new()
    }
}

/// `reply` with its sequence number replaced (streams unchanged).
pub fn with_seq(reply: Reply, new: u16) -> Reply {
    match reply {
        Reply::Ack { .. } => Reply::Ack { seq: new },
        Reply::Nack { error, .. } => Reply::Nack { seq: new, error },
        Reply::Hello {
            version,
            capabilities,
            chip,
            robot,
            ..
        } => Reply::Hello {
            seq: new,
            version,
            capabilities,
            chip,
            robot,
        },
        Reply::Status { status, .. } => Reply::Status { seq: new, status },
        Reply::Param { id, value, .. } => Reply::Param {
            seq: new,
            id,
            value,
        },
        Reply::ClockSync {
            host_time_us,
            robot_time_us,
            ..
        } => Reply::ClockSync {
            seq: new,
            host_time_us,
            robot_time_us,
        },
        Reply::TrajectoryAck {
            next_index, free, ..
        } => Reply::TrajectoryAck {
            seq: new,
            next_index,
            free,
        },
        Reply::RobotRejected { fault, .. } => Reply::RobotRejected { seq: new, fault },
        Reply::RobotData {
            total_len,
            offset,
            data,
            ..
        } => Reply::RobotData {
            seq: new,
            total_len,
            offset,
            data,
        },
        Reply::WheelTestDone { result, .. } => Reply::WheelTestDone { seq: new, result },
        r @ (Reply::FrameError { .. } | Reply::Telemetry(_) | Reply::Event(_)) => r,
    }
}

impl Mux {
    /// No clients, nothing pending.
    pub fn new() -> Self {
        Self {
            next_seq: 0,
            pending: HashMap::new(),
            clients: BTreeSet::new(),
            subs: BTreeMap::new(),
            robot_tel: None,
            counters: MuxCounters::default(),
        }
    }

    /// The server's own telemetry subscription (`wmr serve --live`): part
    /// of the union like a client's, under [`OWN_CLIENT`], which no client
    /// gets (client ids start at 1).
    pub fn set_own_telemetry(&mut self, sub: TelemetrySub) {
        self.subs.insert(OWN_CLIENT, sub);
    }

    /// A client connected.
    pub fn add_client(&mut self, id: ClientId) {
        self.clients.insert(id);
    }

    /// Connected clients.
    pub fn clients(&self) -> usize {
        self.clients.len()
    }

    /// Requests waiting for their answer.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// The telemetry the robot is to send: the union of the groups and the
    /// highest rate any client asked for.
    pub fn union(&self) -> TelemetrySub {
        let on: Vec<&TelemetrySub> = self.subs.values().filter(|s| s.rate_hz > 0).collect();
        match on.iter().map(|s| s.rate_hz).max() {
            None => TelemetrySub::OFF,
            Some(rate_hz) => TelemetrySub {
                selection: on.iter().fold(0, |a, s| a | s.selection),
                rate_hz,
            },
        }
    }

    /// A fresh sequence number for the robot: never 0 (streams), never one
    /// still waiting for its answer.
    fn seq(&mut self) -> u16 {
        for _ in 0..=u16::MAX as u32 {
            self.next_seq = self.next_seq.checked_add(1).unwrap_or(1);
            if !self.pending.contains_key(&self.next_seq) {
                return self.next_seq;
            }
        }
        // 65 535 requests in flight: the oldest goes.
        let oldest = self
            .pending
            .iter()
            .min_by_key(|(_, p)| p.at)
            .map(|(s, _)| *s)
            .unwrap_or(1);
        self.pending.remove(&oldest);
        oldest
    }

    fn send(&mut self, req: Request, origin: Origin, kind: Kind, now: Instant) -> Out {
        let seq = self.seq();
        // Not re-sent: what the robot answers late by design (a flash
        // write, a wheel test's result), what must not happen twice (a
        // reboot, a wheel test), and the server's own periodic requests
        // (the next period sends another) or the handshake (its own schedule).
        let resend = !matches!(
            req,
            Request::RobotCommit | Request::Reboot | Request::WheelTest(_)
        ) && !matches!(
            origin,
            Origin::Own(Own::KeepAlive | Own::Status | Own::Hello)
        );
        self.pending.insert(
            seq,
            Pending {
                origin,
                kind,
                at: now,
                req: resend.then(|| req.clone()),
                last_sent: now,
                resends: 0,
            },
        );
        Out::Robot(seq, req)
    }

    /// Requests unanswered for `every` since they were last sent, at most
    /// `max` times each, sent again under the same sequence number (the
    /// robot answers each copy; the first answer is routed, the others
    /// are unmatched): a lost request or answer costs `every` instead of
    /// the client's own answer timeout (D96).
    pub fn resends(&mut self, now: Instant, every: Duration, max: u32) -> Vec<Out> {
        let mut outs = Vec::new();
        for (seq, p) in self.pending.iter_mut() {
            if let Some(req) = &p.req {
                if p.resends < max && now.duration_since(p.last_sent) >= every {
                    p.resends += 1;
                    p.last_sent = now;
                    outs.push(Out::Robot(*seq, req.clone()));
                }
            }
        }
        self.counters.resent += outs.len() as u64;
        outs.sort_by_key(|o| match o {
            Out::Robot(s, _) => *s,
            Out::Client(..) => 0,
        });
        outs
    }

    /// The server's own request.
    pub fn own(&mut self, own: Own, req: Request, now: Instant) -> Out {
        let kind = match req {
            Request::SetTelemetry { selection, rate_hz } => Kind::Telemetry {
                sent: TelemetrySub { selection, rate_hz },
                client_prev: None,
            },
            _ => Kind::Plain,
        };
        self.send(req, Origin::Own(own), kind, now)
    }

    /// The union telemetry setting, sent as the server's own request
    /// (after a reset: the robot boots with telemetry off).
    pub fn telemetry_request(&mut self, now: Instant) -> Out {
        let u = self.union();
        self.own(
            Own::Telemetry,
            Request::SetTelemetry {
                selection: u.selection,
                rate_hz: u.rate_hz,
            },
            now,
        )
    }

    /// A client's request `req` with its sequence number `seq`.
    pub fn from_client(&mut self, id: ClientId, seq: u16, req: Request, now: Instant) -> Vec<Out> {
        let origin = Origin::Client { id, seq };
        let kind = match req {
            Request::SetTelemetry { selection, rate_hz } => {
                let prev = self.subs.get(&id).copied();
                let sub = TelemetrySub { selection, rate_hz };
                if rate_hz == 0 {
                    self.subs.remove(&id);
                } else {
                    self.subs.insert(id, sub);
                }
                let u = self.union();
                if self.robot_tel == Some(u) && selection & !TELEMETRY_ALL == 0 {
                    self.counters.answered_locally += 1;
                    return vec![Out::Client(id, Reply::Ack { seq })];
                }
                self.counters.forwarded += 1;
                let req = Request::SetTelemetry {
                    selection: u.selection | (selection & !TELEMETRY_ALL),
                    rate_hz: u.rate_hz,
                };
                let kind = Kind::Telemetry {
                    sent: u,
                    client_prev: Some((id, prev)),
                };
                return vec![self.send(req, origin, kind, now)];
            }
            Request::SetParam {
                id: ParamId::LinkTimeoutMs,
                value,
            } => Kind::LinkTimeout(value),
            Request::Reboot => Kind::Reboot,
            Request::WheelTest(_) => Kind::WheelTest,
            _ => Kind::Plain,
        };
        self.counters.forwarded += 1;
        vec![self.send(req, origin, kind, now)]
    }

    /// A client disconnected: its subscription and waiting requests go; the
    /// robot's telemetry follows the remaining clients.
    pub fn remove_client(&mut self, id: ClientId, now: Instant) -> Vec<Out> {
        self.clients.remove(&id);
        self.pending
            .retain(|_, p| !matches!(p.origin, Origin::Client { id: c, .. } if c == id));
        let had = self.subs.remove(&id).is_some();
        if had && self.robot_tel != Some(self.union()) {
            vec![self.telemetry_request(now)]
        } else {
            Vec::new()
        }
    }

    /// The robot reset (or the link was re-established): it forgot its
    /// telemetry setting; the answers to requests sent before will never come.
    pub fn robot_reset(&mut self) {
        self.robot_tel = None;
    }

    /// Drops routing entries older than [`PENDING_TTL`].
    pub fn expire(&mut self, now: Instant) {
        self.pending
            .retain(|_, p| now.duration_since(p.at) < PENDING_TTL);
    }

    /// A frame from the robot: what to send to whom, and what the server
    /// learns.
    pub fn from_robot(&mut self, reply: Reply) -> (Vec<Out>, Option<Note>) {
        match &reply {
            Reply::Telemetry(_) => {
                let outs: Vec<Out> = self
                    .subs
                    .iter()
                    .filter(|(_, s)| s.rate_hz > 0)
                    .map(|(id, _)| Out::Client(*id, reply.clone()))
                    .collect();
                self.counters.telemetry_out += outs.len() as u64;
                return (outs, None);
            }
            Reply::Event(_) => {
                let outs: Vec<Out> = self
                    .clients
                    .iter()
                    .map(|id| Out::Client(*id, reply.clone()))
                    .collect();
                self.counters.events_out += outs.len() as u64;
                return (outs, None);
            }
            Reply::FrameError { .. } => {
                self.counters.frame_errors += 1;
                return (Vec::new(), None);
            }
            _ => {}
        }
        let Some(seq) = reply.seq() else {
            return (Vec::new(), None);
        };
        let Some(p) = self.pending.get(&seq).cloned() else {
            self.counters.unmatched += 1;
            return (Vec::new(), None);
        };
        let acked = matches!(reply, Reply::Ack { .. });
        // A wheel test's ack is followed by its result under the same number.
        if !(p.kind == Kind::WheelTest && acked) {
            self.pending.remove(&seq);
        }
        let note = match p.kind {
            Kind::Telemetry { sent, client_prev } => {
                if acked {
                    self.robot_tel = Some(sent);
                } else if let Some((id, prev)) = client_prev {
                    // Refused: the client's setting was not valid.
                    match prev {
                        Some(s) => self.subs.insert(id, s),
                        None => self.subs.remove(&id),
                    };
                }
                None
            }
            Kind::LinkTimeout(v) if acked => Some(Note::LinkTimeoutSet(v)),
            Kind::Reboot if acked => Some(Note::RebootAcked),
            _ => None,
        };
        match p.origin {
            Origin::Client { id, seq: cseq } => {
                self.counters.answers_routed += 1;
                (vec![Out::Client(id, with_seq(reply, cseq))], note)
            }
            Origin::Own(own) => (
                Vec::new(),
                Some(note.unwrap_or(Note::Own(own, Box::new(reply)))),
            ),
        }
    }

    /// The telemetry subscription of client `id` (tests).
    #[cfg(test)]
    fn sub(&self, id: ClientId) -> Option<TelemetrySub> {
        self.subs.get(&id).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wmr_protocol::{ErrorCode, Event, RunStateMsg, Telemetry};

    fn robot_seq(o: &Out) -> u16 {
        match o {
            Out::Robot(s, _) => *s,
            o => panic!("{o:?}"),
        }
    }

    fn tel(seq: u32) -> Reply {
        Reply::Telemetry(Telemetry {
            seq,
            t_robot_us: seq * 10_000,
            t_ref_s: 0.0,
            state: RunStateMsg::Hold,
            tracking: None,
            estimators: None,
            counters: None,
            covariance: None,
        })
    }

    /// Two clients using the same sequence numbers: each answer goes back
    /// to the client that asked, under its own number, whatever order the
    /// robot answers in; an answer nobody waits for goes nowhere.
    #[test]
    fn answers_go_back_to_the_asking_client_under_its_number() {
        let now = Instant::now();
        let mut m = Mux::new();
        m.add_client(1);
        m.add_client(2);
        let a = robot_seq(&m.from_client(1, 7, Request::GetStatus, now)[0]);
        let b = robot_seq(&m.from_client(2, 7, Request::Arm, now)[0]);
        assert_ne!(a, b);
        assert!(a != 0 && b != 0);
        let (out, _) = m.from_robot(Reply::Nack {
            seq: b,
            error: ErrorCode::NoReference,
        });
        assert_eq!(
            out,
            vec![Out::Client(
                2,
                Reply::Nack {
                    seq: 7,
                    error: ErrorCode::NoReference
                }
            )]
        );
        let (out, _) = m.from_robot(Reply::Ack { seq: a });
        assert_eq!(out, vec![Out::Client(1, Reply::Ack { seq: 7 })]);
        // Answered once: a duplicate goes nowhere.
        let (out, _) = m.from_robot(Reply::Ack { seq: a });
        assert!(out.is_empty());
        assert_eq!(m.counters.unmatched, 1);
        assert_eq!(m.pending(), 0);
    }

    /// A client that leaves with a request in flight: its answer is dropped,
    /// the other client's still arrives.
    #[test]
    fn a_client_leaving_mid_request_does_not_disturb_the_others() {
        let now = Instant::now();
        let mut m = Mux::new();
        m.add_client(1);
        m.add_client(2);
        let a = robot_seq(&m.from_client(1, 1, Request::GetStatus, now)[0]);
        let b = robot_seq(&m.from_client(2, 1, Request::GetStatus, now)[0]);
        assert!(m.remove_client(1, now).is_empty());
        assert!(m.from_robot(Reply::Ack { seq: a }).0.is_empty());
        assert_eq!(
            m.from_robot(Reply::Ack { seq: b }).0,
            vec![Out::Client(2, Reply::Ack { seq: 1 })]
        );
    }

    /// The robot sends the union of the clients' telemetry (groups or-ed,
    /// the highest rate); telemetry goes only to clients that turned it
    /// on, events to everyone; when the last subscriber leaves the robot's
    /// telemetry is turned off; a setting the robot already has is
    /// acknowledged by the server.
    #[test]
    fn telemetry_is_the_union_and_fans_out_to_subscribers() {
        let now = Instant::now();
        let mut m = Mux::new();
        for id in 1..=3 {
            m.add_client(id);
        }
        let o = m.from_client(
            1,
            5,
            Request::SetTelemetry {
                selection: 1,
                rate_hz: 100,
            },
            now,
        );
        let s1 = robot_seq(&o[0]);
        assert_eq!(
            o[0],
            Out::Robot(
                s1,
                Request::SetTelemetry {
                    selection: 1,
                    rate_hz: 100
                }
            )
        );
        assert_eq!(
            m.from_robot(Reply::Ack { seq: s1 }).0,
            vec![Out::Client(1, Reply::Ack { seq: 5 })]
        );
        let o = m.from_client(
            2,
            9,
            Request::SetTelemetry {
                selection: 4,
                rate_hz: 5,
            },
            now,
        );
        let s2 = robot_seq(&o[0]);
        assert_eq!(
            o[0],
            Out::Robot(
                s2,
                Request::SetTelemetry {
                    selection: 5,
                    rate_hz: 100
                }
            )
        );
        m.from_robot(Reply::Ack { seq: s2 });
        // The same again (a retry after a lost ack): answered here.
        let o = m.from_client(
            2,
            10,
            Request::SetTelemetry {
                selection: 4,
                rate_hz: 5,
            },
            now,
        );
        assert_eq!(o, vec![Out::Client(2, Reply::Ack { seq: 10 })]);
        let (out, _) = m.from_robot(tel(3));
        assert_eq!(out, vec![Out::Client(1, tel(3)), Out::Client(2, tel(3))]);
        let ev = Reply::Event(Event::LinkLost);
        assert_eq!(m.from_robot(ev.clone()).0.len(), 3);
        // Client 1 leaves: client 2's setting alone.
        let o = m.remove_client(1, now);
        assert_eq!(
            o,
            vec![Out::Robot(
                robot_seq(&o[0]),
                Request::SetTelemetry {
                    selection: 4,
                    rate_hz: 5
                }
            )]
        );
        m.from_robot(Reply::Ack {
            seq: robot_seq(&o[0]),
        });
        let o = m.remove_client(2, now);
        assert_eq!(
            o,
            vec![Out::Robot(
                robot_seq(&o[0]),
                Request::SetTelemetry {
                    selection: TELEMETRY_ALL,
                    rate_hz: 0
                }
            )]
        );
        assert!(m.from_robot(tel(4)).0.is_empty());
    }

    /// A setting the robot refuses (rate above its limit) leaves the
    /// client's previous subscription, and the client gets the refusal.
    #[test]
    fn a_refused_telemetry_setting_is_undone() {
        let now = Instant::now();
        let mut m = Mux::new();
        m.add_client(1);
        let s = robot_seq(
            &m.from_client(
                1,
                1,
                Request::SetTelemetry {
                    selection: 7,
                    rate_hz: 50,
                },
                now,
            )[0],
        );
        m.from_robot(Reply::Ack { seq: s });
        let s = robot_seq(
            &m.from_client(
                1,
                2,
                Request::SetTelemetry {
                    selection: 7,
                    rate_hz: 5000,
                },
                now,
            )[0],
        );
        let (out, _) = m.from_robot(Reply::Nack {
            seq: s,
            error: ErrorCode::InvalidValue,
        });
        assert_eq!(
            out,
            vec![Out::Client(
                1,
                Reply::Nack {
                    seq: 2,
                    error: ErrorCode::InvalidValue
                }
            )]
        );
        assert_eq!(
            m.sub(1),
            Some(TelemetrySub {
                selection: 7,
                rate_hz: 50
            })
        );
    }

    /// A wheel test is answered twice under one number: both answers reach
    /// the client; the server's own answers come back as notes.
    #[test]
    fn wheel_test_answers_twice_and_own_answers_are_notes() {
        let now = Instant::now();
        let mut m = Mux::new();
        m.add_client(1);
        let cmd = wmr_protocol::WheelTestCmd {
            wheel: 0,
            torque_nm: 0.1,
            duration_ms: 100,
        };
        let s = robot_seq(&m.from_client(1, 3, Request::WheelTest(cmd), now)[0]);
        assert_eq!(m.from_robot(Reply::Ack { seq: s }).0.len(), 1);
        assert_eq!(m.pending(), 1);
        let done = Reply::WheelTestDone {
            seq: s,
            result: wmr_protocol::WheelTestResult {
                wheel: 0,
                torque_nm: 0.1,
                duty: 10,
                ticks: 100,
                end: wmr_protocol::WheelTestEnd::Completed,
                counts: [5, 0],
                gyro_yaw_rad: None,
            },
        };
        let (out, _) = m.from_robot(done);
        assert!(matches!(
            out[..],
            [Out::Client(1, Reply::WheelTestDone { seq: 3, .. })]
        ));
        assert_eq!(m.pending(), 0);
        let s = robot_seq(&m.own(Own::KeepAlive, Request::GetStatus, now));
        let (out, note) = m.from_robot(Reply::Ack { seq: s });
        assert!(out.is_empty());
        assert_eq!(
            note,
            Some(Note::Own(Own::KeepAlive, Box::new(Reply::Ack { seq: s })))
        );
    }

    /// An unanswered request is sent again under its number, `max` times,
    /// not before `every`; a reboot, a flash commit and the server's
    /// keep-alives never; an answered one no more.
    #[test]
    fn unanswered_requests_are_resent_under_their_number() {
        let t0 = Instant::now();
        let ms = Duration::from_millis;
        let mut m = Mux::new();
        m.add_client(1);
        let a = robot_seq(&m.from_client(1, 4, Request::Arm, t0)[0]);
        m.from_client(1, 5, Request::Reboot, t0);
        m.from_client(1, 6, Request::RobotCommit, t0);
        m.own(Own::KeepAlive, Request::GetStatus, t0);
        assert!(m.resends(t0 + ms(10), ms(25), 3).is_empty());
        for k in 1..=3 {
            let o = m.resends(t0 + ms(25 * k), ms(25), 3);
            assert_eq!(o, vec![Out::Robot(a, Request::Arm)], "{k}");
        }
        assert!(m.resends(t0 + ms(200), ms(25), 3).is_empty());
        assert_eq!(m.counters.resent, 3);
        let b = robot_seq(&m.from_client(1, 7, Request::GetStatus, t0)[0]);
        m.from_robot(Reply::Ack { seq: b });
        assert!(m.resends(t0 + ms(300), ms(25), 3).is_empty());
    }

    /// Sequence numbers skip 0 and the ones still waiting, across the wrap.
    #[test]
    fn sequence_numbers_skip_zero_and_those_in_flight() {
        let now = Instant::now();
        let mut m = Mux::new();
        m.add_client(1);
        let first = robot_seq(&m.from_client(1, 1, Request::GetStatus, now)[0]);
        assert_eq!(first, 1);
        m.next_seq = u16::MAX - 1;
        let a = robot_seq(&m.from_client(1, 1, Request::GetStatus, now)[0]);
        let b = robot_seq(&m.from_client(1, 1, Request::GetStatus, now)[0]);
        assert_eq!((a, b), (u16::MAX, 2), "0 and 1 (in flight) skipped");
        m.expire(now + PENDING_TTL);
        assert_eq!(m.pending(), 0);
    }
}
