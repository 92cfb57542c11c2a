//! Telemetry and events: what the robot sends without being asked. The
//! telemetry schedule (rate, groups, sequence numbers), the counters it
//! carries, and the state-change events.

use crate::framing::{bump, Framing, LinkCounters};
use crate::params::LinkConfig;
use crate::reference::pose_to_msg;
use controller_core::estimator::OdomCovariance;
use controller_core::runtime::{Status, TickReport};
use wmr_protocol::{
    Counters, CovarianceTelemetry, EstimatorTelemetry, Event, Reply, RunStateMsg, StopCode,
    Telemetry, TrackingTelemetry, MAX_FRAME, TELEMETRY_COUNTERS, TELEMETRY_COVARIANCE,
    TELEMETRY_ESTIMATORS, TELEMETRY_TRACKING,
};

/// Every counter: the runtime's and the link's.
pub(crate) fn counters(s: &Status, link: &LinkCounters) -> Counters {
    Counters {
        ticks: s.ticks,
        run_ticks: s.run_ticks,
        overruns: s.overruns,
        max_loop_time_us: s.max_loop_time_us,
        encoder_jumps: s.encoder_jumps,
        input_faults: s.input_faults,
        torque_saturated: s.torque_saturated,
        duty_saturated: s.duty_saturated,
        external_poses: s.external_poses,
        stops: s.stops,
        rx_frames: link.rx_frames,
        rx_errors: link.rx_errors,
        rx_overflow: link.rx_overflow,
        tx_dropped: link.tx_dropped,
        nacks: link.nacks,
    }
}

/// The telemetry schedule and the last state reported in an event.
pub(crate) struct TelemetryScheduler {
    seq: u32,
    countdown: u32,
    /// Frames not sent because of a non-finite value.
    nonfinite: u32,
    reported_state: RunStateMsg,
}

impl TelemetryScheduler {
    pub fn new() -> Self {
        Self {
            seq: 0,
            countdown: 0,
            nonfinite: 0,
            reported_state: RunStateMsg::Hold,
        }
    }

    /// Frames not sent because a value in them was not finite.
    pub fn nonfinite_frames(&self) -> u32 {
        self.nonfinite
    }

    /// The rate or the groups changed: the next tick sends a frame.
    pub fn restart(&mut self) {
        self.countdown = 0;
    }

    /// Sends a state-change event when `state` differs from the last one
    /// reported; `cause`: the braking cause when stopping, else the stop
    /// not yet reported (taken).
    pub fn report_state(
        &mut self,
        framing: &mut Framing,
        state: RunStateMsg,
        braking_cause: Option<StopCode>,
        pending_cause: &mut Option<StopCode>,
    ) {
        if state != self.reported_state {
            self.reported_state = state;
            let cause = match state {
                RunStateMsg::Running => None,
                RunStateMsg::Stopping => braking_cause,
                _ => pending_cause.take(),
            };
            framing.send(&Reply::Event(Event::StateChanged { state, cause }));
        }
    }

    /// The telemetry frame of this tick, when one is due and fits;
    /// `covariance` is called only for a frame that carries it (never on
    /// the other ticks: D155).
    // Out of line: one copy (smaller firmware; the call costs nothing here).
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub fn tick(
        &mut self,
        framing: &mut Framing,
        link: &LinkConfig,
        period_s: f32,
        now_us: u32,
        state: RunStateMsg,
        status: &Status,
        rep: &TickReport,
        covariance: impl FnOnce() -> OdomCovariance,
    ) {
        let rate = link.telemetry_rate_hz;
        if rate == 0 {
            return;
        }
        if self.countdown > 0 {
            self.countdown -= 1;
            return;
        }
        let every = ((1.0 / (rate as f32 * period_s)) + 0.5) as u32;
        self.countdown = every.max(1) - 1;
        // Keep room for a reply: telemetry only when two frames still fit.
        if framing.tx_free() < 2 * MAX_FRAME {
            bump(&mut framing.counters.tx_dropped);
            self.seq = self.seq.wrapping_add(1);
            return;
        }
        let sel = link.telemetry_selection;
        let d = &rep.diag;
        let duty = rep.duty.map(|c| {
            if c.reverse {
                -(c.duty as i32)
            } else {
                c.duty as i32
            }
        });
        let t = Telemetry {
            seq: self.seq,
            t_robot_us: now_us,
            t_ref_s: rep.t_s,
            state,
            tracking: (sel & TELEMETRY_TRACKING != 0).then(|| TrackingTelemetry {
                pose: pose_to_msg(rep.pose),
                ref_pose: pose_to_msg(rep.reference.pose),
                error: d.error,
                eta: rep.eta.as_array(),
                eta_c: d.eta_c,
                torque_nm: rep.torque_nm,
                duty,
                saturated: d.saturated,
                time_scale: rep.pace.scale,
                tau_s: rep.pace.tau_s,
                health: rep.pace.mode as u8,
                health_reason: rep.pace.reason as u8,
            }),
            estimators: (sel & TELEMETRY_ESTIMATORS != 0).then(|| EstimatorTelemetry {
                s: d.s,
                rho_hat: d.rho_hat,
                d_hat: d.d_hat,
                f_hat: d.f_hat,
                external_pose: rep.external_pose,
                input_fault: d.fault.is_some(),
            }),
            counters: (sel & TELEMETRY_COUNTERS != 0).then(|| counters(status, &framing.counters)),
            covariance: (sel & TELEMETRY_COVARIANCE != 0).then(|| {
                let c = covariance();
                CovarianceTelemetry::from_f32(c.pose, c.twist)
            }),
        };
        self.seq = self.seq.wrapping_add(1);
        // Nothing non-finite goes on the wire: the frame is skipped (its
        // sequence number too, so the host sees the gap) and counted.
        if !t.is_finite() {
            bump(&mut self.nonfinite);
            return;
        }
        framing.send(&Reply::Telemetry(t));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::runtime::{
        ControlLoop, DutyCommand, MotorDriver, NoGyro, RuntimeConfig, TickTiming, WheelEncoders,
        WheelOdometryOnly,
    };
    use controller_core::ControllerKind;
    use wmr_protocol::TELEMETRY_ALL;

    struct Still;
    impl WheelEncoders for Still {
        fn counts(&mut self) -> [u16; 2] {
            [0; 2]
        }
    }
    struct Off;
    impl MotorDriver for Off {
        fn set(&mut self, _: [DutyCommand; 2]) {}
        fn disable(&mut self) {}
    }

    /// A report with a NaN or an infinity in it (a runtime fault) is not
    /// sent: counted, its sequence number skipped; a finite one is sent.
    #[test]
    fn nonfinite_frames_are_withheld_and_counted() {
        let mut control =
            ControlLoop::new(RuntimeConfig::example(ControllerKind::Proposed)).unwrap();
        let rep = control.tick(
            &mut Still,
            &mut Off,
            &mut NoGyro,
            &mut WheelOdometryOnly,
            TickTiming::on_schedule_at(1000, 1000),
        );
        let link = LinkConfig {
            telemetry_rate_hz: 1000,
            telemetry_selection: TELEMETRY_ALL,
            ..LinkConfig::DEFAULT
        };
        let status = *control.status();
        let mut framing = Framing::new();
        let mut t = TelemetryScheduler::new();
        let mut bad = [rep; 3];
        bad[0].reference.pose.x_m = f32::NAN;
        bad[1].diag.eta_c[0] = f32::INFINITY;
        bad[2].t_s = f32::NAN;
        for r in &bad {
            t.tick(
                &mut framing,
                &link,
                1e-3,
                0,
                RunStateMsg::Running,
                &status,
                r,
                OdomCovariance::default,
            );
        }
        assert_eq!(framing.tx_len(), 0, "a non-finite frame went out");
        assert_eq!(t.nonfinite_frames(), 3);
        t.tick(
            &mut framing,
            &link,
            1e-3,
            0,
            RunStateMsg::Running,
            &status,
            &rep,
            OdomCovariance::default,
        );
        assert!(framing.tx_len() > 0, "a finite frame is sent");
        assert_eq!(t.seq, 4, "sequence numbers of withheld frames are skipped");
    }
}
