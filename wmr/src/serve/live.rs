//! `wmr serve --live`: the robot's telemetry as the MCAP logs' topics on a
//! Foxglove WebSocket server (ros-mcap's `LiveView`). The view starts at
//! the robot's hello (its geometry: r and h from `RobotInfo`, d the
//! paper's, as `wmr record --mcap`); stamps are host Unix time mapped
//! from the first frame's arrival.

use ros_mcap::live::{LiveArgs, LiveView};
use ros_mcap::{Geometry, LogFrame, TimeMap};
use wmr_protocol::{Reply, RobotInfo, Telemetry};

/// The live view of a server.
pub(crate) struct ServeLive {
    at: LiveArgs,
    view: Option<LiveView>,
    time_map: Option<TimeMap>,
}

impl ServeLive {
    /// A view to start on `at`'s address once the robot is known.
    pub fn new(at: LiveArgs) -> Self {
        Self {
            at,
            view: None,
            time_map: None,
        }
    }

    /// The robot answered its hello: starts the view (once); a line for
    /// the server's log.
    pub fn on_hello(&mut self, hello: &Reply) -> Option<String> {
        if self.view.is_some() {
            return None;
        }
        let Reply::Hello { robot, .. } = hello else {
            return None;
        };
        let RobotInfo {
            wheel_radius_m,
            half_track_m,
            ..
        } = *robot;
        let started = Geometry::new(
            wheel_radius_m as f64,
            half_track_m as f64,
            ros_mcap::default_com_offset_m(),
        )
        .map_err(|e| e.to_string())
        .and_then(|g| self.at.start(g, "wmr serve").map_err(|e| e.to_string()));
        Some(match started {
            Ok(v) => {
                let line = format!("live view: {}", self.at.url(v.port()));
                self.view = Some(v);
                line
            }
            Err(e) => e,
        })
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
