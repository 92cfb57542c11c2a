//! The report of a robot's log (`wmr record`, `wmr metrics`): the
//! [`Metrics`] over a window that fits the path the log ran, how late the
//! robot ends against its reference, and its health over the run. A
//! simulation's scenario has a perturbation window (the paper's 10–35 s);
//! a robot's log has none, so its window is the log's own span.

use crate::{metrics_from_trace, Metrics, TraceSample, HEALTH_REASONS};
use serde::Serialize;

/// How far back [`end_lag_s`] looks for the reference point nearest the
/// robot's last position \[s\]: longer than any lag a tracking run has,
/// shorter than a lap of a closed path that returns to its start.
pub const LAG_SEARCH_S: f64 = 5.0;

/// Distance within which two reference points count as equally near
/// \[m\]: the latest of them gives the lag (a reference standing still at
/// its end is reached, not late).
pub const LAG_TIE_M: f64 = 1e-3;

/// What a robot's log says about the run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogReport {
    /// The window of the `*_window_*` metrics: the log's own span,
    /// first to last row \[s\].
    pub window_s: [f64; 2],
    /// The metrics with that window.
    pub metrics: Metrics,
    /// How late the robot ends against its reference \[s\]: the last
    /// row's time minus the time at which the reference passed nearest
    /// the robot's last position (searched over the last
    /// [`LAG_SEARCH_S`]); 0 when the robot reached where the reference is.
    pub end_lag_s: f64,
    /// The distance from the robot's last position to that reference
    /// point (the error the lag does not explain) \[m\].
    pub end_offset_m: f64,
    /// Share of rows in each health mode, and the reasons published.
    pub health: HealthShare,
}

/// Share of a log's rows in each health mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HealthShare {
    /// Nominal.
    pub nominal: f64,
    /// Degraded.
    pub degraded: f64,
    /// Safe stop.
    pub safe_stop: f64,
    /// Each reason published outside nominal, by name, with its share of
    /// all rows (most frequent first).
    pub reasons: Vec<(String, f64)>,
}

/// [`LogReport`] of a log; `None` for fewer than two rows with
/// increasing time.
pub fn log_report(trace: &[TraceSample]) -> Option<LogReport> {
    let (first, last) = (trace.first()?, trace.last()?);
    // A window just past the last row holds every row.
    let n = trace.len() as f64;
    let dt = (last.t_s - first.t_s) / (n - 1.0).max(1.0);
    let window_s = [first.t_s, last.t_s + 0.5 * dt];
    let mut metrics = metrics_from_trace(trace, window_s, false)?;
    // Settling until the end, not until the window starts (there is no
    // time before it): the same accumulator without a window.
    metrics.settling_time_s = metrics_from_trace(trace, [0.0, 0.0], false)?.settling_time_s;
    let (end_lag_s, end_offset_m) = end_lag_s(trace)?;
    Some(LogReport {
        window_s: [first.t_s, last.t_s],
        metrics,
        end_lag_s,
        end_offset_m,
        health: health_share(trace),
    })
}

/// How late the robot ends and the offset left: see
/// [`LogReport::end_lag_s`].
pub fn end_lag_s(trace: &[TraceSample]) -> Option<(f64, f64)> {
    let last = trace.last()?;
    let dist = |s: &TraceSample| (s.ref_pose[0] - last.pose[0]).hypot(s.ref_pose[1] - last.pose[1]);
    let recent = trace
        .iter()
        .filter(|s| s.t_s >= last.t_s - LAG_SEARCH_S && dist(s).is_finite());
    let best = recent.clone().map(dist).fold(f64::INFINITY, f64::min);
    if !best.is_finite() {
        return None;
    }
    let t = recent
        .filter(|s| dist(s) <= best + LAG_TIE_M)
        .map(|s| s.t_s)
        .fold(f64::NEG_INFINITY, f64::max);
    Some((last.t_s - t, best))
}

/// Share of rows in each health mode and per reason.
pub fn health_share(trace: &[TraceSample]) -> HealthShare {
    let n = trace.len().max(1) as f64;
    let mut modes = [0usize; 3];
    let mut reasons = [0usize; HEALTH_REASONS.len()];
    for s in trace {
        modes[(s.health as usize).min(2)] += 1;
        if s.health != 0 {
            if let Some(r) = reasons.get_mut(s.health_reason as usize) {
                *r += 1;
            }
        }
    }
    let mut named: Vec<(String, f64)> = reasons
        .iter()
        .enumerate()
        .filter(|(_, &c)| c > 0)
        .map(|(i, &c)| (HEALTH_REASONS[i].to_string(), c as f64 / n))
        .collect();
    named.sort_by(|a, b| b.1.total_cmp(&a.1));
    HealthShare {
        nominal: modes[0] as f64 / n,
        degraded: modes[1] as f64 / n,
        safe_stop: modes[2] as f64 / n,
        reasons: named,
    }
}

impl std::fmt::Display for LogReport {
    /// The human summary: window, errors, lag, health.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = &self.metrics;
        let [t0, t1] = self.window_s;
        writeln!(
            f,
            "tracked {:.2} s ({t0:.2} to {t1:.2} s): RMS position error {:.1} mm over the run, \
             max {:.1} mm, final {:.1} mm{}",
            t1 - t0,
            m.rms_pos_err_window_m * 1e3,
            m.max_pos_err_window_m * 1e3,
            m.final_pos_err_m * 1e3,
            match m.settling_time_s {
                Some(s) => format!(", below 0.1 m from {s:.2} s on"),
                None => ", not settled below 0.1 m".into(),
            }
        )?;
        writeln!(
            f,
            "lag: the robot ends {:.2} s behind its reference ({:.1} mm off the path's point \
             there)",
            self.end_lag_s,
            self.end_offset_m * 1e3
        )?;
        let h = &self.health;
        write!(
            f,
            "health: nominal {:.1} %, degraded {:.1} %, safe stop {:.1} %",
            h.nominal * 1e2,
            h.degraded * 1e2,
            h.safe_stop * 1e2
        )?;
        if !h.reasons.is_empty() {
            let r: Vec<String> = h
                .reasons
                .iter()
                .map(|(n, x)| format!("{n} {:.1} %", x * 1e2))
                .collect();
            write!(f, " ({})", r.join(", "))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reference along x at 0.5 m/s for `duration_s`, the robot
    /// following it `delay_s` late (its pose is the reference's at
    /// t − delay), 100 rows per second.
    fn delayed_line(duration_s: f64, delay_s: f64) -> Vec<TraceSample> {
        let n = (duration_s * 100.0) as usize + 1;
        (0..n)
            .map(|k| {
                let t = k as f64 * 0.01;
                let x_ref = 0.5 * t;
                let x = 0.5 * (t - delay_s).max(0.0);
                TraceSample {
                    t_s: t,
                    ref_pose: [x_ref, 0.0, 0.0],
                    pose: [x, 0.0, 0.0],
                    pos_err_m: x_ref - x,
                    ..Default::default()
                }
            })
            .collect()
    }

    /// The lag of a robot following its reference a known 0.4 s late is
    /// 0.4 s (to a row), its offset 0; on time it is 0.
    #[test]
    fn the_lag_of_a_delayed_robot_is_its_delay() {
        let r = log_report(&delayed_line(12.0, 0.4)).unwrap();
        assert!((r.end_lag_s - 0.4).abs() <= 0.01 + 1e-9, "{}", r.end_lag_s);
        assert!(r.end_offset_m < 1e-9);
        let r = log_report(&delayed_line(12.0, 0.0)).unwrap();
        assert!(r.end_lag_s.abs() < 1e-9, "{}", r.end_lag_s);
    }

    /// The window is the log's own span (a 12 s path: [0, 12] s, not the
    /// paper's [10, 35] s), so the window RMS is the run's: for a robot
    /// 0.4 s late at 0.5 m/s, 0.2 m after 0.4 s and 0.5·t before, RMS
    /// sqrt((∫₀^0.4 (0.5t)² dt + 0.04·11.6) / 12).
    #[test]
    fn the_window_fits_the_path_that_ran() {
        let r = log_report(&delayed_line(12.0, 0.4)).unwrap();
        assert_eq!(r.window_s, [0.0, 12.0]);
        let exact = ((0.25 * 0.4f64.powi(3) / 3.0 + 0.04 * 11.6) / 12.0).sqrt();
        assert!(
            (r.metrics.rms_pos_err_window_m - exact).abs() < 2e-3,
            "{} vs {exact}",
            r.metrics.rms_pos_err_window_m
        );
        assert_eq!(r.metrics.rms_pos_err_window_m, r.metrics.rms_pos_err_m);
        assert!((r.metrics.max_pos_err_window_m - 0.2).abs() < 1e-9);
        // Never below 0.1 m: not settled.
        assert_eq!(r.metrics.settling_time_s, None);
        let r = log_report(&delayed_line(12.0, 0.1)).unwrap();
        assert_eq!(r.metrics.settling_time_s, Some(0.0));
    }

    /// Health: a quarter of the rows degraded for saturation, a tenth in
    /// safe stop for a lost path.
    #[test]
    fn health_shares_count_rows() {
        let mut t = delayed_line(9.99, 0.0);
        assert_eq!(t.len(), 1000);
        for s in &mut t[..250] {
            s.health = 1;
            s.health_reason = 1;
        }
        for s in &mut t[900..] {
            s.health = 2;
            s.health_reason = 7;
        }
        let h = log_report(&t).unwrap().health;
        assert_eq!((h.nominal, h.degraded, h.safe_stop), (0.65, 0.25, 0.1));
        assert_eq!(
            h.reasons,
            vec![
                ("saturation".to_string(), 0.25),
                ("lost path".to_string(), 0.1)
            ]
        );
    }
}
