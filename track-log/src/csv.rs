//! The trace CSV: a header line [`CSV_HEADER`], then one row per
//! [`TraceSample`] (every scalar in header order, `saturated` as 0/1).
//! Unknown values (e.g. the true fault `f_true_*` in a robot log) are `NaN`.

use crate::TraceSample;
use std::fmt::Write as _;
use std::io::{self, BufRead, Write};

/// CSV header of [`write_trace_csv`], one name per [`TraceSample`] scalar.
pub const CSV_HEADER: &str = "t_s,ref_x_m,ref_y_m,ref_theta_rad,x_m,y_m,theta_rad,pos_err_m,\
err_x_m,err_y_m,e_x,e_y,e_theta,v_mps,omega_radps,v_c_mps,omega_c_radps,tau_r_nm,tau_l_nm,\
s_v,s_omega,rho_hat_v,rho_hat_omega,d_hat_v,d_hat_omega,f_hat_v,f_hat_omega,f_true_v,f_true_omega,saturated,\
time_scale,tau_s,health,health_reason";

/// Columns of [`CSV_HEADER`].
pub const CSV_COLUMNS: usize = 34;

/// Leading float columns (before `saturated`).
const FLOATS: usize = 29;

fn values(s: &TraceSample) -> [f64; FLOATS] {
    [
        s.t_s,
        s.ref_pose[0],
        s.ref_pose[1],
        s.ref_pose[2],
        s.pose[0],
        s.pose[1],
        s.pose[2],
        s.pos_err_m,
        s.err_xy_m[0],
        s.err_xy_m[1],
        s.e[0],
        s.e[1],
        s.e[2],
        s.eta[0],
        s.eta[1],
        s.eta_c[0],
        s.eta_c[1],
        s.torque_nm[0],
        s.torque_nm[1],
        s.s[0],
        s.s[1],
        s.rho_hat[0],
        s.rho_hat[1],
        s.d_hat[0],
        s.d_hat[1],
        s.f_hat[0],
        s.f_hat[1],
        s.f_true[0],
        s.f_true[1],
    ]
}

/// Every scalar of `s` in [`CSV_HEADER`] order as f64 (`saturated` as 0
/// or 1): the row [`trace_row`] writes, as numbers (the Python package's
/// trace array).
pub fn trace_values(s: &TraceSample) -> [f64; CSV_COLUMNS] {
    let mut out = [0.0; CSV_COLUMNS];
    out[..FLOATS].copy_from_slice(&values(s));
    out[FLOATS..].copy_from_slice(&[
        f64::from(u8::from(s.saturated)),
        s.time_scale,
        s.tau_s,
        f64::from(s.health),
        f64::from(s.health_reason),
    ]);
    out
}

/// One row (no newline).
pub fn trace_row(s: &TraceSample) -> String {
    let mut line = String::with_capacity(400);
    for v in values(s) {
        let _ = write!(line, "{v},");
    }
    let _ = write!(
        line,
        "{},{},{},{},{}",
        u8::from(s.saturated),
        s.time_scale,
        s.tau_s,
        s.health,
        s.health_reason
    );
    line
}

/// Writes the header and one row per sample.
pub fn write_trace_csv(mut w: impl Write, trace: &[TraceSample]) -> io::Result<()> {
    writeln!(w, "{CSV_HEADER}")?;
    for s in trace {
        writeln!(w, "{}", trace_row(s))?;
    }
    Ok(())
}

/// Reads a trace CSV written by [`write_trace_csv`] (by `hil-sim run --csv`
/// or `wmr record`); `origin` names the source in errors. The header must
/// be [`CSV_HEADER`].
pub fn read_trace_csv(r: impl BufRead, origin: &str) -> Result<Vec<TraceSample>, String> {
    let mut lines = r.lines();
    let header = lines
        .next()
        .ok_or_else(|| format!("{origin}: empty file"))?
        .map_err(|e| format!("{origin}: {e}"))?;
    if header.trim_end() != CSV_HEADER {
        return Err(format!(
            "{origin}: not a trace CSV (the header differs from hil-sim run --csv / wmr record)"
        ));
    }
    let mut out = Vec::new();
    for (i, line) in lines.enumerate() {
        let line = line.map_err(|e| format!("{origin}: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let row = i + 2;
        let cells: Vec<&str> = line.trim_end().split(',').collect();
        if cells.len() != CSV_COLUMNS {
            return Err(format!(
                "{origin}:{row}: {} columns, expected {CSV_COLUMNS}",
                cells.len()
            ));
        }
        let num = |k: usize| -> Result<f64, String> {
            let c = cells[k];
            c.parse()
                .map_err(|_| format!("{origin}:{row}: column {} is not a number: {c:?}", k + 1))
        };
        let index = |k: usize| -> Result<u8, String> {
            let c = cells[k];
            c.parse().map_err(|_| {
                format!(
                    "{origin}:{row}: column {} is not a small integer: {c:?}",
                    k + 1
                )
            })
        };
        let mut v = [0.0f64; FLOATS];
        for (k, x) in v.iter_mut().enumerate() {
            *x = num(k)?;
        }
        let saturated = match cells[FLOATS] {
            "0" => false,
            "1" => true,
            c => {
                return Err(format!(
                    "{origin}:{row}: saturated must be 0 or 1, not {c:?}"
                ))
            }
        };
        out.push(TraceSample {
            t_s: v[0],
            ref_pose: [v[1], v[2], v[3]],
            pose: [v[4], v[5], v[6]],
            pos_err_m: v[7],
            err_xy_m: [v[8], v[9]],
            e: [v[10], v[11], v[12]],
            eta: [v[13], v[14]],
            eta_c: [v[15], v[16]],
            torque_nm: [v[17], v[18]],
            s: [v[19], v[20]],
            rho_hat: [v[21], v[22]],
            d_hat: [v[23], v[24]],
            f_hat: [v[25], v[26]],
            f_true: [v[27], v[28]],
            saturated,
            time_scale: num(FLOATS + 1)?,
            tau_s: num(FLOATS + 2)?,
            health: index(FLOATS + 3)?,
            health_reason: index(FLOATS + 4)?,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(k: usize) -> TraceSample {
        let x = k as f64 * 0.123_456_789_012_345;
        TraceSample {
            t_s: k as f64 * 0.01,
            ref_pose: [x, -x, 0.1],
            pose: [x + 1e-9, 2.0, -3.0],
            pos_err_m: 1.0 / 3.0,
            torque_nm: [f64::MIN_POSITIVE, -1e300],
            f_true: [f64::NAN, 0.0],
            saturated: k % 2 == 0,
            time_scale: 0.25 * (k % 5) as f64,
            tau_s: k as f64 * 0.007,
            health: (k % 3) as u8,
            health_reason: (k % 9) as u8,
            ..TraceSample::default()
        }
    }

    #[test]
    fn header_matches_row_width_and_count() {
        let trace = vec![TraceSample::default(); 7];
        let mut buf = Vec::new();
        write_trace_csv(&mut buf, &trace).unwrap();
        let text = String::from_utf8(buf).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 8);
        assert_eq!(lines[0], CSV_HEADER);
        assert_eq!(CSV_HEADER.split(',').count(), CSV_COLUMNS);
        assert!(lines[1..]
            .iter()
            .all(|l| l.split(',').count() == CSV_COLUMNS));
    }

    /// The numbers of [`trace_values`] are the row's cells: the CSV cell
    /// parsed back is the same f64, bit for bit (NaN as NaN).
    #[test]
    fn trace_values_are_the_rows_cells() {
        for k in 0..12 {
            let s = sample(k);
            let row = trace_row(&s);
            let cells: Vec<f64> = row.split(',').map(|c| c.parse().unwrap()).collect();
            let v = trace_values(&s);
            assert_eq!(cells.len(), v.len());
            for (a, b) in cells.iter().zip(v) {
                assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "{a} vs {b}"
                );
            }
        }
    }

    /// Rust prints the shortest string that parses back to the same f64:
    /// written and read back, every value is bit-identical (NaN stays NaN).
    #[test]
    fn round_trip_is_exact() {
        let trace: Vec<_> = (0..50).map(sample).collect();
        let mut buf = Vec::new();
        write_trace_csv(&mut buf, &trace).unwrap();
        let back = read_trace_csv(&buf[..], "t").unwrap();
        assert_eq!(back.len(), trace.len());
        for (a, b) in trace.iter().zip(&back) {
            assert_eq!(a.pose, b.pose);
            assert_eq!(a.torque_nm, b.torque_nm);
            assert!(b.f_true[0].is_nan());
            assert_eq!(a.saturated, b.saturated);
            assert_eq!((a.time_scale, a.tau_s), (b.time_scale, b.tau_s));
            assert_eq!((a.health, a.health_reason), (b.health, b.health_reason));
        }
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let e = read_trace_csv(&b"a,b\n1,2\n"[..], "x.csv").unwrap_err();
        assert!(e.contains("x.csv") && e.contains("header"), "{e}");
        let text = format!("{CSV_HEADER}\n1,2,3\n");
        let e = read_trace_csv(text.as_bytes(), "x.csv").unwrap_err();
        assert!(e.contains("x.csv:2") && e.contains("columns"), "{e}");
    }
}
