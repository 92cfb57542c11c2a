//! The simulated robot behind the host link (`hil-sim device --pty`): the
//! link handler the firmware runs ([`wmr_device::Device`]), the firmware
//! runtime inside it, and the simulated robot (sim-robot's plant,
//! encoders and H-bridge), closed tick by tick as in [`crate::hil`], and
//! served over a pseudo-terminal so that `wmr` talks to it exactly as to a
//! robot.
//!
//! Robot time is simulated time (one control period per tick); `--speed N`
//! paces the ticks N times faster than the wall clock.

use crate::hil::SimSensors;
use crate::scenario::{Scenario, Sensing};
use crate::sim::controller_config;
use controller_core::runtime::{LoopTimer, TickReport};
use controller_core::ControllerKind;
use sim_robot::{
    MotorDrive, PerturbationGrid, Plant, PlantParams, PlantState, SimDriver, SimEncoders,
};
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use wmr_device::{Device, DeviceConfig, LinkConfig};
use wmr_protocol::{CAP_EXTERNAL_POSE, CAP_SIMULATED, CAP_TRAJECTORY, CAP_VELOCITY};

/// The link handler, the runtime and the simulated robot, one tick at a time.
pub struct SimRobot {
    device: Device,
    timer: LoopTimer,
    plant: Plant,
    state: PlantState,
    perturb: PerturbationGrid,
    encoders: SimEncoders,
    bridge: SimDriver,
    scn: Scenario,
    sensors: SimSensors,
    step: u64,
}

impl SimRobot {
    /// The robot of `scn` (at rest at `initial_pose`, in hold) with the
    /// runtime running `kind` at the scenario's gains and the simulated
    /// sensors of its sensing preset (`ideal` is served as `mocap`: the
    /// runtime always reads encoders); external poses sent by the host go to
    /// the same estimator.
    pub fn new(scn: &Scenario, kind: ControllerKind) -> Result<Self, String> {
        scn.validate()?;
        let scn = &Scenario {
            sensing: match scn.sensing {
                Sensing::Ideal => Sensing::Mocap,
                s => s,
            },
            ..scn.clone()
        };
        let (sensors, estimator) = SimSensors::of(scn)?;
        let controller = controller_config(scn, kind);
        let cfg = scn.runtime_config(controller, crate::hil::HilOptions::default().safety);
        let p0 = scn.initial_pose;
        let dev_cfg = DeviceConfig {
            chip: "sim",
            capabilities: CAP_EXTERNAL_POSE | CAP_TRAJECTORY | CAP_VELOCITY | CAP_SIMULATED,
            link: LinkConfig::DEFAULT,
            button_reference: None,
        };
        let device =
            Device::with_estimator(dev_cfg, cfg, estimator).map_err(|e| format!("device: {e}"))?;
        let timer = LoopTimer::from_config(&cfg).map_err(|e| format!("loop timer: {e}"))?;
        let plant = Plant::new(PlantParams::from_robot(
            &controller.robot,
            scn.mass_scale,
            scn.inertia_scale,
        ));
        let substep_s = scn.control_period_s / scn.substeps as f64;
        Ok(Self {
            device,
            timer,
            plant,
            state: PlantState {
                q: [p0[0], p0[1], p0[2], 0.0, 0.0],
                nu: [0.0, 0.0],
            },
            perturb: PerturbationGrid::new(scn.perturbations(), 0.5 * substep_s),
            encoders: SimEncoders::new(&cfg.encoder),
            bridge: SimDriver::default(),
            scn: scn.clone(),
            sensors,
            step: 0,
        })
    }

    /// The link handler.
    pub fn device(&mut self) -> &mut Device {
        &mut self.device
    }

    /// The true pose of G \[x m, y m, θ rad\].
    pub fn true_pose(&self) -> [f64; 3] {
        [self.state.q[0], self.state.q[1], self.state.q[2]]
    }

    /// Robot time of the next tick \[µs\] (wraps like a firmware clock).
    pub fn now_us(&self) -> u32 {
        (self.step * self.timer.period_us() as u64) as u32
    }

    /// Ticks run.
    pub fn ticks(&self) -> u64 {
        self.step
    }

    /// One control period: sensors, the device tick (requests, runtime),
    /// then the plant over the period with the H-bridge held.
    pub fn step(&mut self) -> Result<TickReport, String> {
        let scn = &self.scn;
        let dt = scn.control_period_s;
        let t = self.step as f64 * dt;
        let st = self.state;
        self.encoders.set_angles([st.q[3], st.q[4]]);
        let yaw_rate = self.plant.q_dot(&st, &self.perturb.at(t))[2];
        self.sensors
            .update(t, yaw_rate, [st.q[0], st.q[1], st.q[2]]);
        let now_us = self.now_us();
        let timing = self.timer.tick(now_us);
        let (gyro, pose_source) = self.sensors.parts();
        let rep = self.device.tick(
            now_us,
            &mut self.encoders,
            &mut self.bridge,
            gyro,
            pose_source,
            timing,
        );
        let cfg = self.device.control().config();
        let actuation = MotorDrive {
            model: *self.device.control().motor_model(),
            bridge: self.bridge,
            inverted: cfg.motor_inverted,
        };
        let h = dt / scn.substeps as f64;
        let perturb = &mut self.perturb;
        for j in 0..scn.substeps {
            let t_j = t + j as f64 * h;
            self.state = self
                .plant
                .rk4_step(&self.state, t_j, h, &actuation, &mut |t| perturb.at(t));
        }
        if !Plant::state_is_finite(&self.state) {
            return Err(format!("plant state diverged at t = {t:.3} s"));
        }
        self.step += 1;
        Ok(rep)
    }
}

/// Serves `robot` on `port` (the master side of a pseudo-terminal, or any
/// byte stream with non-blocking reads) until `stop` is set: per tick, the
/// bytes that fit into the receive buffer in, one tick, the queued bytes
/// out (dropped when the other side does not read, like a USB CDC with no
/// host). Ticks are paced at `speed` × real time; a host that falls
/// behind never slows the robot.
pub fn serve(
    robot: &mut SimRobot,
    port: &mut (impl Read + Write),
    speed: f64,
    stop: &AtomicBool,
) -> Result<(), String> {
    let period = Duration::from_secs_f64(robot.scn.control_period_s / speed);
    let start = Instant::now();
    let mut next = start;
    let mut rx = [0u8; 512];
    let mut tx = Vec::with_capacity(4096);
    while !stop.load(Ordering::Relaxed) {
        let room = robot.device.rx_free().min(rx.len());
        if room > 0 {
            match port.read(&mut rx[..room]) {
                Ok(n) => {
                    robot.device.push_rx(&rx[..n]);
                }
                Err(e) if transient(&e) => {}
                Err(e) => return Err(format!("pty read: {e}")),
            }
        }
        robot.step()?;
        if tx.is_empty() {
            let mut buf = [0u8; 4096];
            let n = robot.device.pop_tx(&mut buf);
            tx.extend_from_slice(&buf[..n]);
        }
        if !tx.is_empty() {
            match port.write(&tx) {
                Ok(n) => {
                    tx.drain(..n);
                }
                Err(e) if transient(&e) => {}
                Err(e) => return Err(format!("pty write: {e}")),
            }
        }
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else if now - next > Duration::from_millis(100) {
            // Far behind (a loaded machine): do not try to catch up.
            next = now;
        }
    }
    Ok(())
}

fn transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(e.kind(), TimedOut | WouldBlock | Interrupted)
}

/// A pseudo-terminal pair for the simulated robot: the master side for
/// [`serve`] (non-blocking reads and writes) and the slave side, kept
/// open so that hosts can come and go; returns (master, slave, slave path).
pub fn open_pty() -> Result<(serialport::TTYPort, serialport::TTYPort, String), String> {
    use serialport::SerialPort;
    let (mut master, slave) =
        serialport::TTYPort::pair().map_err(|e| format!("cannot open a pseudo-terminal: {e}"))?;
    master
        .set_timeout(Duration::ZERO)
        .map_err(|e| format!("pty: {e}"))?;
    let path = slave
        .name()
        .ok_or_else(|| "pty: the slave side has no path".to_string())?;
    Ok((master, slave, path))
}
