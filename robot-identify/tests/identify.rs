//! Acceptance tests of the identification, closed through the code that
//! ships: the simulated robot of `hil-sim device` (wmr-device's link
//! handler, the firmware runtime with its pose estimator, and sim-robot's
//! World behind simulated 16-bit encoders, the PWM H-bridge into the DC
//! motor model, the preset gyro with noise, bias and bias walk, and the
//! motion-capture pose source), driven over its link with the frames
//! `wmr identify run` sends (the excitation uploaded as streamed
//! waypoints, telemetry at 1 kHz), the log built from the telemetry frames
//! as `wmr identify run` builds it, and the fit of `wmr identify fit`.
//!
//! Truth: the plant's own parameters (the scenario scales mass and
//! inertia away from the robot the runtime is configured with); the
//! simulated wheels have no friction yet (sim-robot has no friction
//! model), so the friction estimates must be consistent with zero and
//! small against the torques; the EMF constant κ = N·k + c_v/a is then
//! the example motor's N·k = 12 × 0.05 = 0.6 V·s/rad.

use controller_core::trajectory::Excitation;
use controller_core::{ControllerKind, Pose};
use hil_sim::device::SimRobot;
use hil_sim::scenario::{Scenario, Sensing};
use robot_identify::excitation::waypoints;
use robot_identify::{identify, FitOptions, IdRow, Identification, Prior, RowBuilder};
use std::collections::VecDeque;
use wmr_protocol::{
    encode, Decoded, ErrorCode, Event, FrameDecoder, Reply, Request, RobotInfo, RunStateMsg,
    Waypoint, MAX_FRAME, PROTOCOL_VERSION, SEGMENT_POINTS, TELEMETRY_ALL,
};

/// The host side of the link, in process: frames out, replies in.
struct Host {
    out: VecDeque<u8>,
    dec: FrameDecoder<MAX_FRAME>,
    seq: u16,
}

impl Host {
    fn send(&mut self, req: &Request) -> u16 {
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_FRAME];
        let f = encode(req, self.seq, &mut buf).unwrap();
        self.out.extend(f.iter().copied());
        self.seq
    }

    /// One control period of the robot with the host's bytes in and its
    /// replies decoded.
    fn tick(&mut self, robot: &mut SimRobot) -> Vec<Reply> {
        let n = robot.port_rx_room().min(self.out.len());
        if n > 0 {
            let bytes: Vec<u8> = self.out.drain(..n).collect();
            assert_eq!(robot.port_received(&bytes), n);
        }
        robot.step().unwrap();
        let mut buf = [0u8; 8192];
        let n = robot.port_take_tx(&mut buf);
        let mut replies = Vec::new();
        self.dec.feed_all::<Reply>(&buf[..n], |d| {
            if let Decoded::Frame { msg, .. } = d {
                replies.push(msg);
            }
        });
        replies
    }
}

/// What a run gave: the log and the robot's handshake constants.
struct Run {
    rows: Vec<IdRow>,
    info: RobotInfo,
    telemetry_frames: usize,
}

/// The telemetry rate of the runs \[Hz\]: the highest of `wmr identify
/// run`'s probe rates at which the firmware's link carries every group
/// without a gap. robot-app's control task moves at most 128 bytes a tick
/// to the port (`TX_BYTES_PER_TICK`) and a frame of every group is longer:
/// at 1 kHz the simulated robot, running robot-app's loop (D140), delivered
/// 48,870 of some 60,000 frames and the fit found no gap-free horizon.
const TELEMETRY_HZ: u16 = 500;

/// Drives the excitation on the simulated robot of `scn` over its link.
fn run(scn: &Scenario, ex: &Excitation) -> Run {
    let mut robot = SimRobot::new(scn, ControllerKind::Proposed).unwrap();
    let mut host = Host {
        out: VecDeque::new(),
        dec: FrameDecoder::new(),
        seq: 0,
    };
    let p0 = scn.initial_pose;
    let pts: Vec<Waypoint> = waypoints(ex, Pose::new(p0[0] as f32, p0[1] as f32, p0[2] as f32));
    let segs: Vec<Request> = pts
        .chunks(SEGMENT_POINTS)
        .enumerate()
        .map(|(k, c)| Request::TrajectorySegment {
            first_index: (k * SEGMENT_POINTS) as u32,
            points: c.iter().copied().collect(),
        })
        .collect();
    host.send(&Request::Hello {
        version: PROTOCOL_VERSION,
    });
    host.send(&Request::SetTelemetry {
        selection: TELEMETRY_ALL,
        rate_hz: TELEMETRY_HZ,
    });
    host.send(&Request::TrajectoryBegin {
        total_points: pts.len() as u32,
    });
    let mut info = None;
    let mut builder: Option<RowBuilder> = None;
    let (mut next, mut in_flight, mut retry_at) = (0usize, false, 0u64);
    let mut armed = false;
    let mut rows = Vec::new();
    let mut frames = 0;
    let mut seen_running = false;
    let limit = ((ex.duration_s as f64 + 10.0) / scn.control_period_s) as u64;
    for tick in 0..limit {
        if !in_flight && next < segs.len() && tick >= retry_at {
            host.send(&segs[next]);
            in_flight = true;
        }
        if tick % 100 == 0 && armed {
            host.send(&Request::ClockSync {
                host_time_us: tick * 1000,
            });
        }
        let mut ended = false;
        for r in host.tick(&mut robot) {
            match r {
                Reply::Hello { robot, .. } => {
                    info = Some(robot);
                    builder = Some(RowBuilder::new(robot));
                }
                Reply::TrajectoryAck { .. } => {
                    next += 1;
                    in_flight = false;
                }
                Reply::Nack {
                    error: ErrorCode::BufferFull,
                    ..
                } => {
                    in_flight = false;
                    retry_at = tick + 50;
                    if !armed {
                        host.send(&Request::Arm);
                        armed = true;
                    }
                }
                Reply::Nack { error, .. } => panic!("refused: {error:?}"),
                Reply::Telemetry(t) => {
                    frames += 1;
                    seen_running |= t.state == RunStateMsg::Running;
                    if let Some(row) = builder.as_mut().unwrap().row(&t) {
                        rows.push(row);
                    }
                }
                Reply::Event(Event::StateChanged { state, cause })
                    if seen_running
                        && matches!(state, RunStateMsg::Hold | RunStateMsg::Stopped) =>
                {
                    assert_eq!(
                        cause,
                        Some(wmr_protocol::StopCode::TrajectoryEnd),
                        "the run must end with its trajectory"
                    );
                    ended = true;
                }
                _ => {}
            }
        }
        if !armed && next == segs.len() && !in_flight {
            host.send(&Request::Arm);
            armed = true;
        }
        if ended {
            break;
        }
    }
    assert!(seen_running, "the robot never ran");
    Run {
        rows,
        info: info.unwrap(),
        telemetry_frames: frames,
    }
}

/// The identification scenario: the paper robot with the plant's mass and
/// inertia scaled, no section-4 perturbation, hardware sensing of `sensing`.
fn scenario(mass_scale: f64, inertia_scale: f64, sensing: Sensing, seed: u64) -> Scenario {
    let mut scn = Scenario {
        name: "identify".into(),
        initial_pose: [0.0, 0.0, 0.0],
        seed,
        ..Scenario::default()
    };
    let p = &mut scn.perturbations;
    p.beta = 0.0;
    p.eps = 0.0;
    p.skid_scale = 0.0;
    p.disturbance_nm = 0.0;
    scn.plant.mass_scale = mass_scale;
    scn.plant.inertia_scale = inertia_scale;
    scn.sensing.preset = sensing;
    scn
}

fn prior_of(scn: &Scenario) -> Prior {
    Prior {
        robot: controller_core::RobotParams::paper(),
        motor: scn.motor(),
        control_period_s: scn.control_period_s,
        speed_window_ticks: scn.encoder().speed_window_ticks as u32,
        radius_scale: scn.encoder().radius_scale.map(|s| s as f64),
    }
}

fn excitation() -> Excitation {
    Excitation::for_limits(1.0, 2.0)
}

/// The plant's truth for the paper robot scaled by the scenario.
struct Truth {
    mass_kg: f64,
    inertia_kgm2: f64,
}

fn truth(scn: &Scenario) -> Truth {
    let p = controller_core::RobotParams::paper();
    Truth {
        mass_kg: p.mass_kg as f64 * scn.plant.mass_scale,
        inertia_kgm2: p.inertia_kgm2 as f64 * scn.plant.inertia_scale,
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Checks the acceptance margins; returns the relative errors
/// (mass, inertia, radius R, radius L, track, κ mean) for the printout.
/// `radius_scale`: what the radii are expected to read relative to the
/// truth (1 with external poses; with the gyro alone the heading is the
/// gyro's, so r/h reads high by the gyro's scale error).
fn check(id: &Identification, scn: &Scenario, with_poses: bool, radius_scale: f64) -> [f64; 6] {
    let t = truth(scn);
    let p = controller_core::RobotParams::paper();
    let d = id.dynamics.as_ref().expect("dynamics");
    let e_m = rel(d.mass_kg.value, t.mass_kg);
    let e_i = rel(d.inertia_kgm2.value, t.inertia_kgm2);
    let r = p.wheel_radius_m as f64 * radius_scale;
    let e_r = [
        rel(id.wheel_radius_m[0].value, r),
        rel(id.wheel_radius_m[1].value, r),
    ];
    let e_h = rel(id.half_track_m.value, p.half_track_m as f64);
    let nk = 0.6;
    let k = d.emf_vs_per_rad.expect("voltage form");
    let e_k = rel(0.5 * (k[0].value + k[1].value), nk);
    let report = robot_identify::report::text(id, &prior_of(scn));
    assert!(
        e_m < 0.05,
        "mass {:.4} vs {}: {e_m:.4}\n{report}",
        d.mass_kg.value,
        t.mass_kg
    );
    assert!(
        e_i < 0.10,
        "inertia {} vs {}: {e_i:.4}\n{report}",
        d.inertia_kgm2.value,
        t.inertia_kgm2
    );
    assert!(e_r[0] < 0.005 && e_r[1] < 0.005, "radii {e_r:?}\n{report}");
    if with_poses {
        assert!(!id.track_from_prior);
        assert!(e_h < 0.01, "track {e_h}\n{report}");
    } else {
        assert!(id.track_from_prior, "{report}");
    }
    assert!(e_k < 0.2, "EMF constant {k:?}: {e_k}\n{report}");
    // No friction in the plant: each friction estimate is small against
    // the torques the run used (|c_c| < 0.05 N·m, |c_v|·(typical 3 rad/s)
    // < 0.05 N·m), whether or not its interval contains 0.
    for i in 0..2 {
        assert!(
            d.coulomb_nm[i].value.abs() < 0.05,
            "Coulomb {:?}\n{report}",
            d.coulomb_nm
        );
        assert!(
            d.viscous_nms_per_rad[i].value.abs() * 3.0 < 0.05,
            "viscous {:?}\n{report}",
            d.viscous_nms_per_rad
        );
    }
    // Two methods agree: the voltage form's inertia and the torque form's
    // (commanded torques, a different right-hand side) within 2 % (with
    // the torque-limited rows in the voltage form they differed by 4 %).
    let tq = id.torque_check.as_ref().expect("torque form");
    assert!(
        rel(d.inertia_kgm2.value, tq.inertia_kgm2.value) < 0.02,
        "voltage {} torque {}\n{report}",
        d.inertia_kgm2,
        tq.inertia_kgm2
    );
    // The intervals are honest: the truth lies inside the mass and
    // inertia intervals widened by 2 (filter and alignment biases).
    assert!(
        (d.mass_kg.value - t.mass_kg).abs() < 2.0 * d.mass_kg.ci95 + 0.02 * t.mass_kg,
        "{report}"
    );
    [e_m, e_i, e_r[0], e_r[1], e_h, e_k]
}

/// Mocap + gyro: every parameter of the acceptance list, several seeds,
/// mass and inertia away from the robot's configuration.
#[test]
fn identifies_the_paper_robot_with_mocap_and_gyro() {
    for (seed, ms, is) in [(1u64, 1.0, 1.0), (2, 1.3, 0.7), (3, 0.8, 1.5)] {
        let scn = scenario(ms, is, Sensing::Mocap, seed);
        let r = run(&scn, &excitation());
        assert!(
            r.telemetry_frames > 55 * TELEMETRY_HZ as usize,
            "{} frames",
            r.telemetry_frames
        );
        assert_eq!(r.info.wheel_radius_m, 0.1);
        let id = identify(&r.rows, &prior_of(&scn), &FitOptions::default()).unwrap();
        let e = check(&id, &scn, true, 1.0);
        println!(
            "seed {seed} mass×{ms} inertia×{is}: rel. errors mass {:.4} inertia {:.4} r_R {:.5} r_L {:.5} track {:.5} κ {:.4}",
            e[0], e[1], e[2], e[3], e[4], e[5]
        );
        println!("{}", robot_identify::report::text(&id, &prior_of(&scn)));
    }
}

/// Gyro only (no external poses): the radii from the heading with the
/// track from the prior, and the report says the track was not identified.
/// The heading is the gyro's, which reads `scale_error` (0.5 %) high: the
/// radii read high by the same factor (within the 0.5 % margin of it),
/// the limit of a gyro-only calibration (book/src/how-to/identification.md).
#[test]
fn gyro_only_keeps_the_track_from_the_prior_and_says_so() {
    let scn = scenario(1.2, 1.2, Sensing::Imu, 4);
    let r = run(&scn, &excitation());
    let id = identify(&r.rows, &prior_of(&scn), &FitOptions::default()).unwrap();
    let scale = 1.0 + sim_robot::sensors::PRESET_GYRO.scale_error;
    let e = check(&id, &scn, false, scale);
    println!(
        "gyro only: rel. errors mass {:.4} inertia {:.4} r_R/(1+s) {:.5} r_L/(1+s) {:.5} κ {:.4}",
        e[0], e[1], e[2], e[3], e[5]
    );
    assert!(
        id.notes.iter().any(|n| n.contains("no external poses")),
        "{:?}",
        id.notes
    );
    assert!(!id.half_track_m.ci95.is_finite());
}

/// A tiny seeded generator (SplitMix64) for the property test.
fn splitmix(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// Property: over robots drawn at random around the example (mass ×0.7 to
/// ×1.4, inertia ×0.6 to ×1.6 of the configured robot; seeded), the fit
/// meets every margin. (Per-wheel radius and friction mismatch need the
/// plant fields sim-robot does not have yet.)
#[test]
fn random_robots_are_identified() {
    let mut st = 0x1D_u64;
    for k in 0..4 {
        let ms = 0.7 + 0.7 * splitmix(&mut st);
        let is = 0.6 + 1.0 * splitmix(&mut st);
        let scn = scenario(ms, is, Sensing::Mocap, 100 + k);
        let r = run(&scn, &excitation());
        let id = identify(&r.rows, &prior_of(&scn), &FitOptions::default()).unwrap();
        let e = check(&id, &scn, true, 1.0);
        println!("draw {k}: mass×{ms:.3} inertia×{is:.3}: rel. errors {e:.4?}");
    }
}

/// A run without yaw excitation (ω a hundredth of the default; the yaw
/// left is the controller's own corrections): the inertia's interval is
/// at least three times wider than from the default excitation on the
/// same robot and seed (the information in ω̇ falls), and the report
/// carries the interval and the regressor's condition number. (Measured
/// with waypoints every 50 ms: ±0.0129 against ±0.0029 kg·m², 4.5 times;
/// cond 3.75 against 3.67.) The condition number is not asserted to order
/// the two: with waypoints every 25 ms (issue 31: no yaw-rate spikes where
/// the excitation reverses) it came out 3.43 poor against 3.62 rich, so a
/// 2 % difference of either sign says nothing; the interval, which is what
/// the excitation's poverty costs, does.
#[test]
fn a_poor_excitation_is_reported() {
    let scn = scenario(1.0, 1.0, Sensing::Mocap, 7);
    let fit = |ex: &Excitation| {
        let r = run(&scn, ex);
        identify(&r.rows, &prior_of(&scn), &FitOptions::default()).unwrap()
    };
    let rich = fit(&excitation());
    let poor = fit(&Excitation {
        omega_amp_radps: 0.01,
        ..excitation()
    });
    let (dr, dp) = (
        rich.dynamics.unwrap(),
        poor.dynamics.as_ref().unwrap().clone(),
    );
    let text = robot_identify::report::text(&poor, &prior_of(&scn));
    assert!(
        dp.inertia_kgm2.relative_ci() > 3.0 * dr.inertia_kgm2.relative_ci(),
        "poor {:?} rich {:?}\n{text}",
        dp.inertia_kgm2,
        dr.inertia_kgm2
    );
    assert!(text.contains("condition number"));
    println!(
        "rich: inertia {:.4} (cond {:.2}); poor: inertia {:.4} (cond {:.2})",
        dr.inertia_kgm2, dr.lsq.condition, dp.inertia_kgm2, dp.lsq.condition
    );
}

/// A trace log (track-log's CSV: η and torques, no duties) of the same
/// kind of run: the torque form only, said in the notes, with the mass and
/// inertia within the margins; the motor is not identified.
#[test]
fn a_trace_log_gives_the_torque_form() {
    let scn = scenario(1.1, 0.9, Sensing::Mocap, 5);
    let r = run(&scn, &excitation());
    let p = controller_core::RobotParams::paper();
    let (rr, h) = (p.wheel_radius_m as f64, p.half_track_m as f64);
    // The trace rows as `wmr record` writes them (η from the wheel rates).
    let trace: Vec<track_log::TraceSample> = r
        .rows
        .iter()
        .map(|row| {
            let w = row.wheel_rate_radps;
            track_log::TraceSample {
                t_s: row.t_s,
                pose: row.pose,
                eta: [rr * (w[0] + w[1]) / 2.0, rr * (w[0] - w[1]) / (2.0 * h)],
                torque_nm: row.torque_nm,
                saturated: row.saturated,
                ..Default::default()
            }
        })
        .collect();
    let rows = robot_identify::log::rows_from_trace(&trace, &p, true);
    let id = identify(&rows, &prior_of(&scn), &FitOptions::default()).unwrap();
    let d = id.dynamics.as_ref().unwrap();
    let t = truth(&scn);
    let text = robot_identify::report::text(&id, &prior_of(&scn));
    assert_eq!(d.form, robot_identify::Form::Torque, "{text}");
    assert!(d.emf_vs_per_rad.is_none() && id.torque_check.is_none());
    assert!(id.notes.iter().any(|n| n.contains("no duties")), "{text}");
    assert!(rel(d.mass_kg.value, t.mass_kg) < 0.05, "{text}");
    assert!(rel(d.inertia_kgm2.value, t.inertia_kgm2) < 0.10, "{text}");
}

/// D218: a weighed mass fixes the scale only through the run's M_v/a. A
/// run that turns on the spot (v_amp 1 mm/s: v̇ ≈ 0) does not determine
/// it (it fits 1695 ± 226 for a true 15/1.02, explaining 0.6 of the
/// residual): the fit says so instead of writing a = m/(M_v/a) from a
/// number that could be anything (it wrote a +535 % torque per volt for a robot whose
/// friction ate its excitation, and a later run's negative M_v/a refused
/// the whole bring-up), and the robot file gets the weighed mass with the
/// prior's motor. The rich run with the same mass fixes the scale.
#[test]
fn a_weighed_mass_fixes_the_scale_only_when_the_run_determines_it() {
    let scn = scenario(1.0, 1.0, Sensing::Mocap, 8);
    let prior = prior_of(&scn);
    let opts = FitOptions {
        mass_kg: Some(15.0),
        ..FitOptions::default()
    };
    let spin = run(
        &scn,
        &Excitation {
            v_amp_mps: 0.001,
            ..excitation()
        },
    );
    let id = identify(&spin.rows, &prior, &opts).unwrap();
    let d = id.dynamics.as_ref().unwrap();
    let text = robot_identify::report::text(&id, &prior);
    println!("M_v/a {} (spin)\n{text}", d.scale_term);
    assert!(!d.translation_determined() && d.scale_snr < 1.0, "{text}");
    assert!(!d.mass_given() && d.weighed_mass_kg == Some(15.0), "{text}");
    assert_eq!(d.torque_per_volt.value, prior.torque_per_volt());
    assert!(d.torque_per_volt.ci95.is_infinite());
    assert!(
        text.contains("scale NOT identified although the robot was weighed"),
        "{text}"
    );
    let base = robot_file::Robot::paper();
    let (file, _) = robot_identify::report::robot_file(&id, &prior, &base).unwrap();
    let r = robot_file::Robot::from_toml_str(&file).unwrap();
    assert_eq!(r.body.mass_kg, 15.0);
    assert_eq!(r.motors.gear_efficiency, base.motors.gear_efficiency);
    assert_eq!(r.motors.resistance_ohm, base.motors.resistance_ohm);
    let rich = identify(&run(&scn, &excitation()).rows, &prior, &opts).unwrap();
    let d = rich.dynamics.as_ref().unwrap();
    println!("M_v/a {} (rich), a {}", d.scale_term, d.torque_per_volt);
    assert!(d.mass_given() && d.translation_determined() && d.scale_snr > 1.0);
    assert!(rel(d.torque_per_volt.value, prior.torque_per_volt()) < 0.05);
}
