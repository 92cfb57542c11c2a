//! `hil-sim run`: one scenario with one controller.

use super::controller_arg::ControllerArg;
use super::scenario_args::ScenarioArgs;
use crate::progress::Progress;
use crate::report::{run_text, write_trace_csv};
use crate::sim::{controller_config, run_with};
use clap::Args;
use controller_core::ControllerKind;
use std::io::Write;
use std::path::PathBuf;

/// `run` options.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Controller.
    #[arg(long, value_enum, default_value = "proposed")]
    pub controller: ControllerArg,
    /// Scenario.
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Write the trace (every TraceSample field, with a header) to this CSV file.
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Trace decimation for --csv: one row every N control steps [default: 10 ms worth].
    #[arg(long, value_name = "N")]
    pub csv_every: Option<usize>,
    /// Also write the trace as a ROS 2 MCAP log (ros-mcap: /odom, /tf,
    /// /joint_states, /diagnostics, /wmr/tracking), the topics of `wmr record --mcap`.
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<PathBuf>,
    /// Stream the run as it runs to Foxglove (a ws-protocol WebSocket
    /// server; the topics and schemas of --mcap; book/src/how-to/foxglove.md), paced at
    /// real time: each row published when the wall clock reaches its
    /// time since the start.
    #[arg(long)]
    pub live: bool,
    /// --live-host, --live-port.
    #[command(flatten)]
    pub live_at: ros_mcap::live::LiveArgs,
    /// With --live: wait until a client has subscribed to every topic
    /// before simulating (nothing is missed), and after the run (and its
    /// --mcap log) until the clients have left.
    #[arg(long, requires = "live")]
    pub live_wait: bool,
    /// Print exactly one JSON object (the metrics plus "controller", "scenario", "rejected_steps", "runtime_stop": the runtime's latched stop, {"t_s", "reason"} or null).
    #[arg(long)]
    pub json: bool,
    /// Write a --csv estimated beyond 1 GB (the trace is held in memory: at
    /// most 8 GB even so).
    #[arg(long)]
    pub force: bool,
}

/// `run`: one scenario with one controller; the summary or one JSON object,
/// the trace to `--csv`.
pub fn run(a: &RunArgs, out: &mut dyn Write) -> Result<(), String> {
    let scn = a.scenario.build()?;
    crate::limits::check_scenario(&scn)?;
    crate::limits::check_within_robot(&scn)?;
    if a.scenario.case == Some(1) && a.scenario.flags.get::<f64>("eps").is_some_and(|e| e > 0.0) {
        eprintln!("note: --eps with --case 1 injects the actuator fault of Case 2");
    }
    let kind: ControllerKind = a.controller.into();
    let traced = a.csv.is_some() || a.mcap.is_some() || a.live;
    let every = match (traced, a.csv_every) {
        (false, _) => 0,
        (true, Some(n)) => n.max(1),
        (true, None) => crate::sim::trace_every(&scn),
    };
    if traced {
        crate::limits::check_csv(&scn, every, a.force)?;
    }
    let r = controller_config(&scn, kind).robot;
    let geometry = || {
        ros_mcap::Geometry::new(
            r.wheel_radius_m as f64,
            r.half_track_m as f64,
            r.com_offset_m as f64,
        )
        .map_err(|e| e.to_string())
    };
    let live = if a.live {
        Some(super::live::LiveRun::start(
            &a.live_at,
            geometry()?,
            a.live_wait,
        )?)
    } else {
        None
    };
    // One start for the live stamps and the log's: the same messages.
    let start_ns = ros_mcap::unix_now_ns();
    let what = format!(
        "run: simulating {:.0} s of robot time ({:.2e} plant steps)",
        scn.duration_s,
        crate::limits::plant_steps(&scn)
    );
    let sim = || run_with(&scn, controller_config(&scn, kind), every);
    // The live view serves until the end of this function: after the log.
    let (res, view) = match live {
        None => (Progress::during(&what, false, sim)?, None),
        Some(l) => {
            let (res, view) = l.run(start_ns, sim)?;
            (res, Some(view))
        }
    };
    if let Some(path) = &a.csv {
        let f = std::fs::File::create(path)
            .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        write_trace_csv(std::io::BufWriter::new(f), &res.trace)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    if let Some(path) = &a.mcap {
        ros_mcap::write_sim_trace(path, geometry()?, &res.trace, start_ns)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if let (Some(v), true) = (&view, a.live_wait) {
        eprintln!("live view: run over; serving until the clients leave");
        v.wait_for_clients_to_leave();
    }
    let text = run_text(kind, &scn, &res, a.csv.as_deref(), a.json);
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())
}
