//! Temporary driver; the full CLI comes with the hil-sim issue.
use controller_core::ControllerKind;
use hil_sim::{run, Scenario};

fn main() {
    for case in [1u8, 2] {
        let scn = Scenario::paper_case(case, 1, None, None);
        for kind in ControllerKind::ALL {
            let t0 = std::time::Instant::now();
            let out = run(&scn, kind).expect("run");
            let m = &out.metrics;
            println!(
                "case{case} {:9} rms {:.4} win {:.4} maxwin {:.4} after5 {:.4} fin {:.4} settle {:?} trms {:.3} tmax {:.2} chat {:.1} sat {:.3} fe {:?} ({:?})",
                kind.name(), m.rms_pos_err_m, m.rms_pos_err_window_m, m.max_pos_err_window_m, m.rms_pos_err_after5_m,
                m.final_pos_err_m, m.settling_time_s, m.torque_rms_nm, m.max_abs_torque_nm, m.chatter, m.saturated_fraction, m.fault_est_rmse, t0.elapsed()
            );
        }
    }
}
