//! The paper table (`hil-sim compare`'s first table, `metrics.json`) against
//! the same table of the build before issue 17's speed work (commit eb68ee7,
//! `hil-sim compare --out DIR`, both cases, seed 1, the paper's setting, one
//! RK4 step per period): an independent earlier implementation of the same
//! runs. The speed work changed rounding only (D57: the plant's series
//! constants as products; the perturbation grid's repeated instants) and the
//! reference's trigonometry (D58: one sin/cos per sample, as accurate as the
//! three it replaces against f64).
//!
//! Stated tolerance (D58, BENCHMARKS.md): every position metric within
//! 10 µm, the torque RMS within 10⁻⁴ N·m, settling time and saturated fraction
//! equal (to the millisecond), the fault-estimate RMSE within 10⁻⁵, the
//! chatter within 4 % (measured: at most 0.8 µm, 7·10⁻⁷ N·m, 1.4·10⁻⁷ and
//! 2.6 %: the chatter is the torque's total variation, which the switching
//! laws make sensitive to the f32 rounding pattern of the reference).

use controller_core::ControllerKind;
use hil_sim::{run, Scenario};

/// (case, controller, [rms, rms window, max window, rms after 5 s, final] \[m\],
/// settling \[s\], torque RMS \[N·m\], chatter \[N·m/s\], saturated fraction,
/// fault-estimate RMSE), from eb68ee7's `metrics.json`.
type Row = (
    u8,
    ControllerKind,
    [f64; 5],
    f64,
    f64,
    f64,
    f64,
    Option<f64>,
);

#[rustfmt::skip]
const EB68EE7: [Row; 6] = [
    // case 1, smc
    (1, ControllerKind::Smc, [0.6005561800603709, 0.054261173339533224, 0.13233032939738945, 0.046938028466066636, 0.0036300113753283863], 3.525, 1.983547385369053, 7.426238399115391, 0.02795, None),
    // case 1, asmc
    (1, ControllerKind::Asmc, [0.6034002796454105, 0.04242022082748393, 0.11905011938768632, 0.03891151393613987, 0.0012906217232061762], 3.644, 1.95906720882541, 7.466356004448608, 0.02765, None),
    // case 1, proposed
    (1, ControllerKind::Proposed, [0.7251184282657294, 0.036608769730559106, 0.11884234666511125, 0.03196972295331481, 0.0006061704592404752], 4.604, 2.647914266363726, 11.245203670719638, 0.0706, Some(0.04572954615346102)),
    // case 2, smc
    (2, ControllerKind::Smc, [0.6198393697133825, 0.19866102307132213, 0.292112075276617, 0.17058186150342783, 0.003860732950447454], 3.525, 1.9809652507358, 6.438899105344899, 0.02795, None),
    // case 2, asmc
    (2, ControllerKind::Asmc, [0.6220341267740422, 0.1929274901431156, 0.3003212127871499, 0.1661648065629439, 0.0006131105414298491], 3.644, 1.961028356778557, 6.623257273202762, 0.02765, None),
    // case 2, proposed
    (2, ControllerKind::Proposed, [0.7252898037793132, 0.040981956629767884, 0.12128953711287536, 0.03614051534396999, 0.0008119422052181193], 4.604, 2.6780098721167223, 11.576775389583782, 0.0706, Some(0.061299612780911006)),
];

#[test]
fn paper_table_matches_the_build_before_the_speed_work() {
    for (case, kind, pos, settle, tau_rms, chatter, sat, f_rmse) in EB68EE7 {
        let scn = Scenario::paper_case(case, 1, None, None).as_printed();
        let m = run(&scn, kind).unwrap().metrics;
        let got = [
            m.rms_pos_err_m,
            m.rms_pos_err_window_m,
            m.max_pos_err_window_m,
            m.rms_pos_err_after5_m,
            m.final_pos_err_m,
        ];
        for i in 0..5 {
            assert!(
                (got[i] - pos[i]).abs() < 1e-5,
                "case {case} {kind:?} position metric {i}: {} vs {}",
                got[i],
                pos[i]
            );
        }
        assert_eq!(m.settling_time_s, Some(settle), "case {case} {kind:?}");
        assert!(
            (m.torque_rms_nm - tau_rms).abs() < 1e-4,
            "case {case} {kind:?}"
        );
        assert!(
            (m.chatter - chatter).abs() < 0.04 * chatter,
            "case {case} {kind:?} chatter {} vs {chatter}",
            m.chatter
        );
        assert_eq!(m.saturated_fraction, sat, "case {case} {kind:?}");
        match (m.fault_est_rmse, f_rmse) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-5, "case {case} {kind:?}"),
            (a, b) => assert_eq!(a, b, "case {case} {kind:?}"),
        }
    }
}
