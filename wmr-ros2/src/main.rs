//! `wmr-ros2`: the ROS 2 bridge's binary (book/src/how-to/ros2.md). The wiring only:
//! DDS entities from [`wmr_ros2::topics`], messages moved between them
//! and [`wmr_ros2::Bridge`].

use clap::Parser;
use controller_core::runtime::param_table::RobotBounds;
use ros2_client::parameters::raw::{ParameterType, SetParametersResult};
use ros2_client::rcl_interfaces as rcl;
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    Subscription,
};
use serde::{de::DeserializeOwned, Serialize};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use wmr_ros2::bridge::{Bridge, Config, Fatal, Outcome};
use wmr_ros2::cli::{Args, CmdVelType, Mapping};
use wmr_ros2::msg::{
    Path, PoseWithCovarianceStamped, SetOdometryRequest, SetOdometryResponse, TriggerRequest,
    TriggerResponse, TwistStamped,
};
use wmr_ros2::params;
use wmr_ros2::rpc::{self, Accept};
use wmr_ros2::services::{self, Service, ServiceHost};
use wmr_ros2::topics::{self, TopicSpec};

/// Set by SIGINT or SIGTERM: the bridge ends on purpose.
static STOP: AtomicBool = AtomicBool::new(false);

extern "C" fn on_signal(_: libc::c_int) {
    STOP.store(true, Ordering::Relaxed);
}

fn catch_signals() {
    let h = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
    // SAFETY: the handler only stores to an atomic (async-signal-safe).
    unsafe {
        libc::signal(libc::SIGINT, h);
        libc::signal(libc::SIGTERM, h);
    }
}

fn leak(s: &str) -> &'static str {
    Box::leak(s.to_string().into_boxed_str())
}

fn name_of(full: &str) -> Result<Name, String> {
    Name::parse(full).map_err(|e| format!("topic name {full:?}: {e:?}"))
}

fn publisher<T: Serialize>(node: &mut Node, t: &TopicSpec) -> Result<Publisher<T>, String> {
    let topic = node
        .create_topic(
            &name_of(t.name)?,
            MessageTypeName::new(t.package, t.type_name),
            &t.qos(),
        )
        .map_err(|e| format!("topic {}: {e:?}", t.name))?;
    node.create_publisher(&topic, None)
        .map_err(|e| format!("publisher {}: {e:?}", t.name))
}

fn subscription<T: 'static>(node: &mut Node, t: &TopicSpec) -> Result<Subscription<T>, String> {
    let topic = node
        .create_topic(
            &name_of(t.name)?,
            MessageTypeName::new(t.package, t.type_name),
            &t.qos(),
        )
        .map_err(|e| format!("topic {}: {e:?}", t.name))?;
    node.create_subscription(&topic, None)
        .map_err(|e| format!("subscription {}: {e:?}", t.name))
}

/// The node's parameter services (D123; `wmr_ros2::params`), answering
/// each caller in its own service mapping (D150).
struct ParamServers {
    get: Service<rcl::GetParametersRequest, rcl::GetParametersResponse>,
    types: Service<rcl::GetParameterTypesRequest, rcl::GetParameterTypesResponse>,
    set: Service<rcl::SetParametersRequest, rcl::SetParametersResponse>,
    list: Service<rcl::ListParametersRequest, rcl::ListParametersResponse>,
    describe: Service<rcl::DescribeParametersRequest, rcl::DescribeParametersResponse>,
}

/// Takes every request of `srv`: refused ones (not answerable in their
/// caller's mapping) are noted and not acted on; the others are answered
/// with `answer`'s response.
fn serve_all<Q, S, E>(
    srv: &mut Service<Q, S>,
    notes: &mut Vec<String>,
    mut answer: impl FnMut(Q) -> Result<S, E>,
) -> Result<(), E>
where
    Q: DeserializeOwned,
    S: Serialize,
{
    while let Some(r) = srv.take() {
        match r {
            Err(refused) => notes.push(format!("service {refused}")),
            Ok((call, q)) => {
                let resp = answer(q)?;
                if !srv.reply(&call, &resp) {
                    notes.push(format!("{}: response not sent", srv.name()));
                }
            }
        }
    }
    Ok(())
}

impl ParamServers {
    /// Requests refused unanswered, over the five services.
    fn refused(&self) -> u64 {
        self.get.refused
            + self.types.refused
            + self.set.refused
            + self.list.refused
            + self.describe.refused
    }

    fn new(host: &ServiceHost, node_name: &str) -> Result<Self, String> {
        let n = |s: &str| format!("/{node_name}/{s}");
        let rcl = "rcl_interfaces";
        let e = |e: services::CreateError| e.to_string();
        Ok(Self {
            get: host
                .service(&n("get_parameters"), rcl, "GetParameters")
                .map_err(e)?,
            types: host
                .service(&n("get_parameter_types"), rcl, "GetParameterTypes")
                .map_err(e)?,
            set: host
                .service(&n("set_parameters"), rcl, "SetParameters")
                .map_err(e)?,
            list: host
                .service(&n("list_parameters"), rcl, "ListParameters")
                .map_err(e)?,
            describe: host
                .service(&n("describe_parameters"), rcl, "DescribeParameters")
                .map_err(e)?,
        })
    }

    /// Answers every pending request; the values come from the robot and
    /// go to it through the link. Returns a line for each refused set.
    fn serve(&mut self, b: &mut Bridge) -> Result<Vec<String>, Fatal> {
        let mut notes = Vec::new();
        serve_all(&mut self.get, &mut notes, |req| {
            let mut values = Vec::new();
            for name in &req.names {
                values.push(match params::find(name) {
                    Some(p) => p.ros_value(b.get_param(p.id)?),
                    None => params::value(ParameterType::NOT_SET),
                });
            }
            Ok::<_, Fatal>(rcl::GetParametersResponse { values })
        })?;
        serve_all(&mut self.types, &mut notes, |req| {
            let values = req
                .names
                .iter()
                .map(|n| params::find(n).map_or(ParameterType::NOT_SET, |p| p.ros_type()))
                .collect();
            Ok::<_, Fatal>(rcl::GetParameterTypesResponse { values })
        })?;
        let mut set_notes = Vec::new();
        serve_all(&mut self.set, &mut notes, |req| {
            let mut results = Vec::new();
            for q in &req.parameter {
                let r = match params::find(&q.name) {
                    None => Err(match wmr::params::from_old_name(&q.name) {
                        Some(id) => format!("{} was renamed to {}", q.name, id.name()),
                        None => format!(
                            "{}: no such parameter (wmr_ros2 offers the robot's: {})",
                            q.name,
                            params::list(&[], 0).names.join(", ")
                        ),
                    }),
                    // The table's range for any robot (the robot checks
                    // its own robot-dependent bound).
                    Some(p) => match p.robot_value(&q.value, &RobotBounds::ABSOLUTE) {
                        Err(e) => Err(e.to_string()),
                        Ok(v) => match b.set_param(p.id, v)? {
                            Ok(_) => Ok(()),
                            Err(refusal) => Err(format!("{} = {v}: {refusal}", q.name)),
                        },
                    },
                };
                if let Err(e) = &r {
                    set_notes.push(format!("set_parameters: {e}"));
                } else {
                    eprintln!("wmr-ros2: parameter {} set on the robot", q.name);
                }
                results.push(SetParametersResult {
                    successful: r.is_ok(),
                    reason: r.err().unwrap_or_default(),
                });
            }
            Ok::<_, Fatal>(rcl::SetParametersResponse { results })
        })?;
        notes.extend(set_notes);
        serve_all(&mut self.list, &mut notes, |req| {
            let l = params::list(&req.prefixes, req.depth);
            let result = rcl::ListParametersResult {
                names: l.names,
                prefixes: l.prefixes,
            };
            Ok::<_, Fatal>(rcl::ListParametersResponse { result })
        })?;
        serve_all(&mut self.describe, &mut notes, |req| {
            let values = req
                .names
                .iter()
                .map(|n| match params::find(n) {
                    Some(p) => p.descriptor(None),
                    None => ros2_client::parameters::raw::ParameterDescriptor {
                        name: n.clone(),
                        r#type: ParameterType::NOT_SET,
                        description: String::new(),
                        additional_constraints: String::new(),
                        read_only: true,
                        dynamic_typing: false,
                        floating_point_range: Vec::new(),
                        integer_range: Vec::new(),
                    },
                })
                .collect();
            Ok::<_, Fatal>(rcl::DescribeParametersResponse { values })
        })?;
        Ok(notes)
    }
}

struct Pubs {
    odom: Publisher<ros_mcap::msg::Odometry>,
    tf: Publisher<ros_mcap::msg::TfMessage>,
    joints: Publisher<ros_mcap::msg::JointState>,
    diag: Publisher<ros_mcap::msg::DiagnosticArray>,
    tracking: Publisher<ros_mcap::msg::Tracking>,
    /// Publications the DDS layer refused (a full send window).
    dropped: u64,
}

impl Pubs {
    fn publish(&mut self, m: ros_mcap::RosMessages) {
        let mut ok = true;
        ok &= self.odom.publish(m.odom).is_ok();
        ok &= self.tf.publish(m.tf).is_ok();
        ok &= self.joints.publish(m.joints).is_ok();
        ok &= self.tracking.publish(m.tracking).is_ok();
        if let Some(d) = m.diagnostics {
            ok &= self.diag.publish(d).is_ok();
        }
        if !ok {
            self.dropped += 1;
        }
    }
}

enum CmdVelSub {
    Stamped(Subscription<TwistStamped>),
    Plain(Subscription<ros_mcap::msg::Twist>),
}

fn report(what: &str, r: Outcome) -> Result<Option<String>, Fatal> {
    match r? {
        Ok(_) => Ok(None),
        Err(refusal) => {
            let m = format!("{what}: {refusal}");
            Ok(Some(m))
        }
    }
}

fn run(a: &Args) -> Result<(), String> {
    let cfg = Config::new(
        a.rate_hz,
        a.cmd_timeout_ms,
        a.com_offset_m,
        a.path_limit_fraction,
        a.enable,
    )
    .map_err(|e| e.to_string())?;
    if let Some(s) = a.for_s {
        if !(s.is_finite() && s > 0.0) {
            return Err(format!("--for-s {s}: must be > 0"));
        }
    }
    // The port itself, or the `wmr serve` that owns it (book/src/how-to/serve.md):
    // the same `Link` either way.
    let endpoint = wmr::serve::Endpoint::resolve(a.port.as_deref(), a.serve.as_deref())
        .map_err(|e| e.to_string())?;
    let link = wmr::serve::open_link(&endpoint, None).map_err(|e| e.to_string())?;
    let via = match &endpoint {
        wmr::serve::Endpoint::Port(p) => p.clone(),
        wmr::serve::Endpoint::Server(s) => format!("wmr serve at {}", s.display()),
    };
    let mut b = Bridge::connect(link, cfg).map_err(|e| e.to_string())?;
    let mut log = match &a.mcap {
        None => None,
        Some(p) => Some(
            ros_mcap::McapLog::create(p, b.geometry(), "wmr-ros2")
                .map_err(|e| format!("{}: {e}", p.display()))?,
        ),
    };
    let mut live = match a.live {
        false => None,
        true => {
            let v = a
                .live_at
                .start(b.geometry(), "wmr-ros2")
                .map_err(|e| e.to_string())?;
            eprintln!("live view: {}", a.live_at.url(v.port()));
            Some(v)
        }
    };
    let ctx = Context::with_options(ContextOptions::new().domain_id(a.domain_id))
        .map_err(|e| format!("DDS participant: {e:?}"))?;
    let mut node = ctx
        .new_node(
            NodeName::new("/", &a.node_name).map_err(|e| format!("node name: {e:?}"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| format!("node: {e:?}"))?;
    let mut pubs = Pubs {
        odom: publisher(&mut node, &topics::ODOM)?,
        tf: publisher(&mut node, &topics::TF)?,
        joints: publisher(&mut node, &topics::JOINT_STATES)?,
        diag: publisher(&mut node, &topics::DIAGNOSTICS)?,
        tracking: publisher(&mut node, &topics::TRACKING)?,
        dropped: 0,
    };
    let stamped = a.cmd_vel_type.unwrap_or(a.ros_distro.nav2_cmd_vel()) == CmdVelType::Stamped;
    let cv = topics::cmd_vel(leak(&a.cmd_vel_topic), stamped);
    let cmd_vel = if stamped {
        CmdVelSub::Stamped(subscription(&mut node, &cv)?)
    } else {
        CmdVelSub::Plain(subscription(&mut node, &cv)?)
    };
    let path_sub: Subscription<Path> = subscription(&mut node, &topics::path(leak(&a.path_topic)))?;
    let loc_sub: Subscription<PoseWithCovarianceStamped> =
        subscription(&mut node, &topics::localiser(leak(&a.localiser_topic)))?;
    let init_sub: Subscription<PoseWithCovarianceStamped> =
        subscription(&mut node, &topics::INITIAL_POSE)?;
    let accept = match a.service_mapping {
        Mapping::Auto => Accept::Auto,
        Mapping::Enhanced => Accept::Only(rpc::Mapping::Enhanced),
        Mapping::Cyclone => Accept::Only(rpc::Mapping::Cyclone),
    };
    let host = ServiceHost::new(ctx.domain_participant(), accept).map_err(|e| e.to_string())?;
    let mut servers: Vec<Service<TriggerRequest, TriggerResponse>> = Vec::new();
    for s in topics::SERVICES {
        servers.push(
            host.service(s, "std_srvs", "Trigger")
                .map_err(|e| e.to_string())?,
        );
    }
    let mut set_odometry: Service<SetOdometryRequest, SetOdometryResponse> = host
        .service(
            &format!("/{}/{}", a.node_name, topics::SET_ODOMETRY),
            "control_msgs",
            "SetOdometry",
        )
        .map_err(|e| e.to_string())?;
    let mut param_servers = ParamServers::new(&host, &a.node_name)?;
    let limits = b.limits();
    eprintln!(
        "wmr-ros2: bridging {via} on DDS domain {}: robot r {:.4} m, h {:.4} m, {}; limits {:.2} m/s, {:.2} rad/s; motion {}",
        a.domain_id,
        b.geometry().wheel_radius_m,
        b.geometry().half_track_m,
        b.com_offset(),
        limits.max_speed_mps,
        limits.max_yaw_rate_radps,
        if a.enable { "enabled" } else { "disabled until the arm service" }
    );
    catch_signals();
    let started = Instant::now();
    let mut last_note: Option<(String, Instant)> = None;
    let r: Result<(), Fatal> = (|| loop {
        if STOP.load(Ordering::Relaxed)
            || a.for_s
                .is_some_and(|s| started.elapsed().as_secs_f64() >= s)
        {
            return Ok(());
        }
        // Each frame with its own messages (a poll may return several).
        for (f, m) in b.poll(Duration::from_millis(5))? {
            if let Some(l) = &mut log {
                l.write(&f)
                    .map_err(|e| Fatal::Robot(format!("MCAP log: {e}")))?;
            }
            if let Some(v) = &mut live {
                v.publish(&f)
                    .map_err(|e| Fatal::Robot(format!("live view: {e}")))?;
            }
            pubs.publish(m);
        }
        let mut notes = Vec::new();
        loop {
            let tw = match &cmd_vel {
                CmdVelSub::Stamped(s) => s
                    .take()
                    .ok()
                    .flatten()
                    .map(|(m, _)| (m.twist, Some(m.header.stamp.to_ns()))),
                CmdVelSub::Plain(s) => s.take().ok().flatten().map(|(m, _)| (m, None)),
            };
            let Some((tw, stamp)) = tw else { break };
            notes.extend(report("cmd_vel", b.cmd_vel(&tw, stamp))?);
        }
        while let Ok(Some((p, _))) = path_sub.take() {
            notes.extend(report("path", b.path(&p))?);
        }
        while let Ok(Some((p, _))) = loc_sub.take() {
            notes.extend(report("localiser pose", b.localiser_pose(&p))?);
        }
        while let Ok(Some((p, _))) = init_sub.take() {
            notes.extend(report("initialpose", b.initial_pose(&p))?);
        }
        for (k, srv) in servers.iter_mut().enumerate() {
            serve_all(srv, &mut notes, |_req| {
                let out = match k {
                    0 => b.arm()?,
                    1 => b.disarm()?,
                    2 => b.emergency_stop()?,
                    _ => b.clear_stop()?,
                };
                let resp = match out {
                    Ok(m) => TriggerResponse {
                        success: true,
                        message: m,
                    },
                    Err(r) => TriggerResponse {
                        success: false,
                        message: r.to_string(),
                    },
                };
                eprintln!("wmr-ros2: {}: {}", topics::SERVICES[k], resp.message);
                Ok::<_, Fatal>(resp)
            })?;
        }
        serve_all(&mut set_odometry, &mut notes, |req| {
            let resp = match b.set_odometry(&req)? {
                Ok(m) => SetOdometryResponse {
                    success: true,
                    message: m,
                },
                Err(r) => SetOdometryResponse {
                    success: false,
                    message: r.to_string(),
                },
            };
            eprintln!("wmr-ros2: set_odometry: {}", resp.message);
            Ok::<_, Fatal>(resp)
        })?;
        notes.extend(param_servers.serve(&mut b)?);
        b.stats.service_requests_refused = servers.iter().map(|s| s.refused).sum::<u64>()
            + set_odometry.refused
            + param_servers.refused();
        for n in notes {
            // The same refusal again (a publisher at 20 Hz): once every 5 s.
            if last_note
                .as_ref()
                .is_none_or(|(m, t)| *m != n || t.elapsed() >= Duration::from_secs(5))
            {
                eprintln!("wmr-ros2: refused {n}");
                last_note = Some((n, Instant::now()));
            }
        }
    })();
    if let Some(l) = log {
        l.finish().map_err(|e| format!("MCAP log: {e}"))?;
    }
    match r {
        Ok(()) => {
            b.shutdown();
            eprintln!(
                "wmr-ros2: done after {:.1} s: {} frames ({} dropped, {} not published: stamped at or before the last), {} cmd_vel ({} forwarded, {} refused), {} paths ({} uploaded), {}, {} publications dropped",
                started.elapsed().as_secs_f64(),
                b.stats.frames,
                b.stats.frames_dropped,
                b.stats.frames_repeated,
                b.stats.cmd_vel,
                b.stats.cmd_vel_forwarded,
                b.stats.cmd_vel_refused,
                b.stats.paths,
                b.stats.paths_uploaded,
                b.poses,
                pubs.dropped
            );
            Ok(())
        }
        Err(e) => Err(e.to_string()),
    }
}

fn main() -> ExitCode {
    let a = Args::parse();
    match run(&a) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("wmr-ros2: {e}");
            ExitCode::from(wmr_ros2::cli::EXIT_FAILURE)
        }
    }
}
