//! The paper's section-4 figures, regenerated for one case with the three
//! controllers on every figure and the perturbation window shaded, as PNG
//! (bitmap backend) and SVG:
//!
//! | file | paper | content |
//! |---|---|---|
//! | `<case>_xy` | Fig. 3b / 5b | XY paths and the reference |
//! | `<case>_errors` | Fig. 3a / 5a | x_s − x and y_s − y vs time, full run and zoom t ≥ 5 s |
//! | `<case>_velocities` | Fig. 4a / 7a | measured v and ω (encoders) and the reference's v_s, ω_s |
//! | `<case>_torques` | Fig. 4b / 7b | applied wheel torques right / left |
//! | `<case>_faults` | Fig. 6 | proposed controller's F̂ = \[Δv̂, Δω̂\] vs the injected F = ε·η |
//!
//! Text is drawn with plotters' `ab_glyph` renderer from a TrueType file read
//! at run time (no fontconfig, no system libraries at build time):
//! `$HIL_SIM_FONT` if set, else DejaVu Sans (Debian/Ubuntu package
//! `fonts-dejavu-core`) or another sans font from the usual directories.

use crate::scenario::Scenario;
use crate::sim::{SimOutput, TraceSample};
use controller_core::trajectory::Trajectory;
use controller_core::ControllerKind;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

type Res = Result<(), String>;

/// The legend box, styled the same on every figure.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    pos: SeriesLabelPosition,
    font_px: u32,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(pos)
        .label_font(("sans-serif", font_px))
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(160, 160, 160))
        .draw()
        .map_err(err)
}

fn err<E: std::fmt::Display>(e: E) -> String {
    format!("plot: {e}")
}

/// Fonts tried, in order, when `$HIL_SIM_FONT` is unset.
pub const FONT_CANDIDATES: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu-sans-fonts/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/Library/Fonts/Arial.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

fn find_font() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("HIL_SIM_FONT") {
        return Ok(PathBuf::from(p));
    }
    if let Some(p) = FONT_CANDIDATES.iter().map(Path::new).find(|p| p.is_file()) {
        return Ok(p.to_path_buf());
    }
    // Any .ttf under /usr/share/fonts, as a last resort.
    let mut stack = vec![PathBuf::from("/usr/share/fonts")];
    while let Some(dir) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&dir) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("ttf")) {
                return Ok(p);
            }
        }
    }
    Err(
        "plot: no TrueType font found; install one (Debian/Ubuntu: `apt-get install \
         fonts-dejavu-core`) or point HIL_SIM_FONT at a .ttf file"
            .into(),
    )
}

/// Loads the font once per process and registers it for every family
/// plotters asks for. Returns the font file used.
pub fn init_fonts() -> Result<PathBuf, String> {
    static FONT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    FONT.get_or_init(|| {
        let path = find_font()?;
        let bytes = std::fs::read(&path)
            .map_err(|e| format!("plot: cannot read font {}: {e}", path.display()))?;
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        for family in ["sans-serif", "serif", "monospace"] {
            plotters::style::register_font(family, FontStyle::Normal, bytes)
                .map_err(|_| format!("plot: {} is not a usable TrueType font", path.display()))?;
        }
        Ok(path)
    })
    .clone()
}

/// Line colour of a controller (same on every figure).
pub fn color(kind: ControllerKind) -> RGBColor {
    match kind {
        ControllerKind::Smc => RGBColor(214, 39, 40),
        ControllerKind::Asmc => RGBColor(31, 119, 180),
        ControllerKind::Proposed => RGBColor(44, 160, 44),
    }
}

/// Legend label of a controller.
pub fn label(kind: ControllerKind) -> &'static str {
    match kind {
        ControllerKind::Smc => "SMC without observer",
        ControllerKind::Asmc => "ASMC without observer",
        ControllerKind::Proposed => "proposed (fault obs. + ESO + ASMC)",
    }
}

const WINDOW_FILL: RGBAColor = RGBAColor(255, 165, 0, 0.13);
const REF_COLOR: RGBColor = RGBColor(0, 0, 0);

struct Series {
    label: String,
    color: RGBColor,
    dashed: bool,
    width: u32,
    points: Vec<(f64, f64)>,
}

impl Series {
    fn ctrl(kind: ControllerKind, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label(kind).into(),
            color: color(kind),
            dashed: false,
            width: 2,
            points,
        }
    }
    fn reference(label: &str, points: Vec<(f64, f64)>) -> Self {
        Self {
            label: label.into(),
            color: REF_COLOR,
            dashed: true,
            width: 2,
            points,
        }
    }
}

/// y range covering the points with x in `x_range`, padded by 6 % (and never
/// degenerate).
fn y_range(series: &[Series], x_range: &Range<f64>) -> Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &(x, y) in &s.points {
            if x >= x_range.start && x <= x_range.end && y.is_finite() {
                lo = lo.min(y);
                hi = hi.max(y);
            }
        }
    }
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let span = (hi - lo).max(1e-3 * (hi.abs().max(lo.abs())).max(1e-3));
    (lo - 0.06 * span)..(hi + 0.06 * span)
}

struct Panel<'a> {
    title: &'a str,
    x_desc: &'a str,
    y_desc: &'a str,
    x_range: Range<f64>,
    /// None = fit the data inside x_range.
    y_range: Option<Range<f64>>,
    window: Option<[f64; 2]>,
    series: &'a [Series],
    legend: bool,
}

/// Tick label with as many decimals as the axis span needs, and no "-0".
fn tick(v: f64, span: f64) -> String {
    let prec = if span > 0.0 {
        (-(span / 10.0).log10()).ceil().max(0.0) as usize
    } else {
        1
    };
    let s = format!("{v:.prec$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

fn font_px(area_h: u32) -> u32 {
    (area_h / 28).clamp(13, 22)
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Res {
    let (_, h) = area.dim_in_pixel();
    let fs = font_px(h);
    let y_range = p
        .y_range
        .clone()
        .unwrap_or_else(|| y_range(p.series, &p.x_range));
    let mut chart = ChartBuilder::on(area)
        .caption(p.title, ("sans-serif", fs + 3))
        .margin(10)
        .margin_right(30)
        .x_label_area_size(fs * 2 + 8)
        .y_label_area_size(fs * 4 + 10)
        .build_cartesian_2d(p.x_range.clone(), y_range.clone())
        .map_err(err)?;
    let xs = p.x_range.end - p.x_range.start;
    let ys = y_range.end - y_range.start;
    let xf = move |v: &f64| tick(*v, xs);
    let yf = move |v: &f64| tick(*v, ys);
    chart
        .configure_mesh()
        .x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .x_desc(p.x_desc)
        .y_desc(p.y_desc)
        .label_style(("sans-serif", fs))
        .axis_desc_style(("sans-serif", fs + 1))
        .light_line_style(RGBColor(235, 235, 235))
        .x_labels(9)
        .y_labels(7)
        .draw()
        .map_err(err)?;
    if let Some([a, b]) = p.window {
        let (a, b) = (a.max(p.x_range.start), b.min(p.x_range.end));
        if a < b {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y_range.start), (b, y_range.end)],
                    WINDOW_FILL.filled(),
                )))
                .map_err(err)?
                .label("perturbation window")
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 6), (x + 20, y + 6)], WINDOW_FILL.filled())
                });
        }
    }
    for s in p.series {
        // Clip to the visible x range so zoomed panels stay light.
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, _)| *x >= p.x_range.start && *x <= p.x_range.end)
            .collect();
        let style = s.color.stroke_width(s.width);
        let c = s.color;
        let w = s.width;
        let anno = if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(pts, 8, 5, style))
                .map_err(err)?
        } else {
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(err)?
        };
        anno.label(s.label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(w)));
    }
    if p.legend {
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, fs)?;
    }
    Ok(())
}

/// What one figure needs.
struct CaseData<'a> {
    scn: &'a Scenario,
    runs: &'a [SimOutput],
    case_title: String,
}

impl CaseData<'_> {
    fn series(&self, f: impl Fn(&TraceSample) -> f64) -> Vec<Series> {
        self.runs
            .iter()
            .map(|o| Series::ctrl(o.kind, o.trace.iter().map(|s| (s.t_s, f(s))).collect()))
            .collect()
    }
    fn t_range(&self) -> Range<f64> {
        0.0..self.scn.duration_s
    }
    fn window(&self) -> Option<[f64; 2]> {
        let [a, b] = self.scn.perturbations.window_s;
        (a < b).then_some([a, b])
    }
    fn times(&self) -> Vec<f64> {
        self.runs
            .first()
            .map(|o| o.trace.iter().map(|s| s.t_s).collect())
            .unwrap_or_default()
    }
}

fn title_area<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<DrawingArea<DB, Shift>, String> {
    root.fill(&WHITE).map_err(err)?;
    let (_, h) = root.dim_in_pixel();
    let fs = (h / 32).clamp(16, 26);
    root.titled(title, ("sans-serif", fs)).map_err(err)
}

fn fig_xy<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!("{}: XY paths (paper Fig. 3b/5b)", d.case_title),
    )?;
    let mut series: Vec<Series> = d
        .runs
        .iter()
        .map(|o| {
            Series::ctrl(
                o.kind,
                o.trace.iter().map(|s| (s.pose[0], s.pose[1])).collect(),
            )
        })
        .collect();
    if let Some(o) = d.runs.first() {
        series.push(Series::reference(
            "reference",
            o.trace
                .iter()
                .map(|s| (s.ref_pose[0], s.ref_pose[1]))
                .collect(),
        ));
    }
    // Equal scales on both axes: pad the shorter span to the area's aspect.
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for s in &series {
        for &(x, y) in &s.points {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if !x0.is_finite() {
        return Ok(());
    }
    let (w, h) = root.dim_in_pixel();
    let fs = font_px(h);
    let plot_w = w as f64 - (fs * 4 + 30) as f64;
    let plot_h = h as f64 - (fs * 2 + 8 + fs + 30) as f64;
    let aspect = plot_w / plot_h;
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let (mut sx, mut sy) = ((x1 - x0) * 1.08 + 0.1, (y1 - y0) * 1.08 + 0.1);
    if sx / sy < aspect {
        sx = sy * aspect;
    } else {
        sy = sx / aspect;
    }
    let [qx, qy, _] = d.scn.initial_pose;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .margin_right(30)
        .x_label_area_size(fs * 2 + 8)
        .y_label_area_size(fs * 4 + 10)
        .build_cartesian_2d(
            (cx - sx / 2.0)..(cx + sx / 2.0),
            (cy - sy / 2.0)..(cy + sy / 2.0),
        )
        .map_err(err)?;
    let xf = move |v: &f64| tick(*v, sx);
    let yf = move |v: &f64| tick(*v, sy);
    chart
        .configure_mesh()
        .x_label_formatter(&xf)
        .y_label_formatter(&yf)
        .x_desc("x [m]")
        .y_desc("y [m]")
        .label_style(("sans-serif", fs))
        .axis_desc_style(("sans-serif", fs + 1))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for s in &series {
        let style = s.color.stroke_width(s.width);
        let c = s.color;
        let anno = if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(s.points.clone(), 8, 5, style))
                .map_err(err)?
        } else {
            chart
                .draw_series(LineSeries::new(s.points.clone(), style))
                .map_err(err)?
        };
        anno.label(s.label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    chart
        .draw_series(std::iter::once(Circle::new((qx, qy), 6, BLACK.filled())))
        .map_err(err)?
        .label(format!("start q0 = ({qx}, {qy})"))
        .legend(|(x, y)| Circle::new((x + 10, y), 5, BLACK.filled()));
    // The paper curve leaves the top and bottom middle empty.
    draw_legend(&mut chart, SeriesLabelPosition::UpperMiddle, fs)?;
    Ok(())
}

/// Start of the zoomed panels: after the initial transient.
const ZOOM_FROM_S: f64 = 5.0;

fn fig_errors<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!("{}: tracking errors (paper Fig. 3a/5a)", d.case_title),
    )?;
    let panels = root.split_evenly((2, 2));
    let ex = d.series(|s| s.err_xy_m[0]);
    let ey = d.series(|s| s.err_xy_m[1]);
    let zoom = ZOOM_FROM_S.min(d.scn.duration_s)..d.scn.duration_s;
    let specs = [
        ("x_s − x, whole run", "x error [m]", &ex, d.t_range(), true),
        (
            "x_s − x, zoom t ≥ 5 s",
            "x error [m]",
            &ex,
            zoom.clone(),
            false,
        ),
        ("y_s − y, whole run", "y error [m]", &ey, d.t_range(), false),
        ("y_s − y, zoom t ≥ 5 s", "y error [m]", &ey, zoom, false),
    ];
    for (area, (title, yd, s, xr, legend)) in panels.iter().zip(specs) {
        draw_panel(
            area,
            &Panel {
                title,
                x_desc: "t [s]",
                y_desc: yd,
                x_range: xr,
                y_range: None,
                window: d.window(),
                series: s,
                legend,
            },
        )?;
    }
    Ok(())
}

fn fig_velocities<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!(
            "{}: linear and angular velocity from the encoders (paper Fig. 4a/7a)",
            d.case_title
        ),
    )?;
    let reference = d.scn.trajectory.reference();
    let times = d.times();
    let refs: Vec<_> = times
        .iter()
        .map(|&t| (t, reference.sample(t as f32)))
        .collect();
    let mut v = d.series(|s| s.eta[0]);
    v.push(Series::reference(
        "reference v_s",
        refs.iter().map(|(t, r)| (*t, r.v_mps as f64)).collect(),
    ));
    let mut w = d.series(|s| s.eta[1]);
    w.push(Series::reference(
        "reference ω_s",
        refs.iter()
            .map(|(t, r)| (*t, r.omega_radps as f64))
            .collect(),
    ));
    let panels = root.split_evenly((2, 1));
    draw_panel(
        &panels[0],
        &Panel {
            title: "linear velocity v",
            x_desc: "t [s]",
            y_desc: "v [m/s]",
            x_range: d.t_range(),
            y_range: None,
            window: d.window(),
            series: &v,
            legend: true,
        },
    )?;
    draw_panel(
        &panels[1],
        &Panel {
            title: "angular velocity ω",
            x_desc: "t [s]",
            y_desc: "ω [rad/s]",
            x_range: d.t_range(),
            y_range: None,
            window: d.window(),
            series: &w,
            legend: true,
        },
    )
}

fn fig_torques<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!(
            "{}: applied wheel torques, limit ±{} N·m (paper Fig. 4b/7b)",
            d.case_title,
            d.scn.torque_limit_nm()
        ),
    )?;
    let l = d.scn.torque_limit_nm() * 1.08;
    let panels = root.split_evenly((2, 1));
    for (i, (area, name)) in panels
        .iter()
        .zip(["right wheel τ_R", "left wheel τ_L"])
        .enumerate()
    {
        let s = d.series(|s| s.torque_nm[i]);
        draw_panel(
            area,
            &Panel {
                title: name,
                x_desc: "t [s]",
                y_desc: "torque [N·m]",
                x_range: d.t_range(),
                y_range: Some(-l..l),
                window: d.window(),
                series: &s,
                legend: i == 0,
            },
        )?;
    }
    Ok(())
}

fn fig_faults<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!(
            "{}: actuator fault F = ε·η and its estimate (paper Fig. 6){}",
            d.case_title,
            if d.scn.perturbations.eps == 0.0 {
                ", no fault injected"
            } else {
                ""
            }
        ),
    )?;
    let Some(p) = d.runs.iter().find(|o| o.kind == ControllerKind::Proposed) else {
        return Ok(());
    };
    let panels = root.split_evenly((2, 1));
    for (i, (area, (name, yd))) in panels
        .iter()
        .zip([
            ("Δv: fault on the linear velocity", "Δv [m/s]"),
            ("Δω: fault on the angular velocity", "Δω [rad/s]"),
        ])
        .enumerate()
    {
        let s = [
            Series {
                label: "estimate of F (proposed controller)".into(),
                color: color(ControllerKind::Proposed),
                dashed: false,
                width: 2,
                points: p.trace.iter().map(|s| (s.t_s, s.f_hat[i])).collect(),
            },
            Series::reference(
                "injected F = ε·η",
                p.trace.iter().map(|s| (s.t_s, s.f_true[i])).collect(),
            ),
        ];
        draw_panel(
            area,
            &Panel {
                title: name,
                x_desc: "t [s]",
                y_desc: yd,
                x_range: d.t_range(),
                y_range: None,
                window: d.window(),
                series: &s,
                legend: i == 0,
            },
        )?;
    }
    Ok(())
}

/// Reference governor and health machine (drawn only with the governor on):
/// time scale s and health mode per controller.
fn fig_pacing<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    let root = title_area(
        &root,
        &format!(
            "{}: reference governor time scale s and health mode (beyond the paper)",
            d.case_title
        ),
    )?;
    let panels = root.split_evenly((2, 1));
    let s = d.series(|s| s.time_scale);
    draw_panel(
        &panels[0],
        &Panel {
            title: "time scale s (1 = nominal speed, 0 = reference stopped)",
            x_desc: "t [s]",
            y_desc: "s",
            x_range: d.t_range(),
            y_range: Some(-0.05..1.08),
            window: d.window(),
            series: &s,
            legend: true,
        },
    )?;
    let h = d.series(|s| s.health as f64);
    draw_panel(
        &panels[1],
        &Panel {
            title: "health mode: 0 nominal, 1 degraded, 2 safe stop",
            x_desc: "t [s]",
            y_desc: "mode",
            x_range: d.t_range(),
            y_range: Some(-0.2..2.2),
            window: d.window(),
            series: &h,
            legend: false,
        },
    )
}

/// The governor figure's name and size \[px\] (with the governor on only).
const PACING_FIGURE: (&str, (u32, u32)) = ("pacing", (1400, 950));

/// Figure names and sizes \[px\].
const FIGURES: [(&str, (u32, u32)); 5] = [
    ("xy", (1100, 900)),
    ("errors", (1500, 950)),
    ("velocities", (1400, 950)),
    ("torques", (1400, 950)),
    ("faults", (1400, 950)),
];

fn draw_figure<DB: DrawingBackend>(name: &str, root: DrawingArea<DB, Shift>, d: &CaseData) -> Res {
    match name {
        "xy" => fig_xy(root, d),
        "errors" => fig_errors(root, d),
        "velocities" => fig_velocities(root, d),
        "torques" => fig_torques(root, d),
        "pacing" => fig_pacing(root, d),
        _ => fig_faults(root, d),
    }
}

/// Writes `<prefix>_<figure>.png` and `.svg` for every figure into `dir`
/// (created if needed); `runs` holds one traced run per controller of the
/// same scenario. Returns the files written.
pub fn write_case_plots(
    dir: &Path,
    prefix: &str,
    case_title: &str,
    scn: &Scenario,
    runs: &[SimOutput],
) -> Result<Vec<PathBuf>, String> {
    init_fonts()?;
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    if runs.iter().any(|o| o.trace.is_empty()) {
        return Err("plot: runs without a trace".into());
    }
    let d = CaseData {
        scn,
        runs,
        case_title: case_title.into(),
    };
    let mut written = Vec::new();
    let pacing = scn.governor_on().then_some(PACING_FIGURE);
    for (name, size) in FIGURES.into_iter().chain(pacing) {
        let p = dir.join(format!("{prefix}_{name}.png"));
        {
            let root = BitMapBackend::new(&p, size).into_drawing_area();
            draw_figure(name, root.clone(), &d)?;
            root.present().map_err(err)?;
        }
        written.push(p);
        let p = dir.join(format!("{prefix}_{name}.svg"));
        {
            let root = SVGBackend::new(&p, size).into_drawing_area();
            draw_figure(name, root.clone(), &d)?;
            root.present().map_err(err)?;
        }
        written.push(p);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_fit_the_span_and_have_no_negative_zero() {
        assert_eq!(tick(-0.0001, 0.3), "0.00");
        assert_eq!(tick(0.15, 0.3), "0.15");
        assert_eq!(tick(10.0, 40.0), "10");
        assert_eq!(tick(-5.0, 20.0), "-5");
        assert_eq!(tick(1.5, 3.5), "1.5");
    }

    /// Every figure is written as PNG and SVG (skipped when the machine has
    /// no TrueType font at all; CI installs fonts-dejavu-core).
    #[test]
    fn writes_every_figure() {
        if let Err(e) = init_fonts() {
            eprintln!("skipped: {e}");
            return;
        }
        let mut scn = Scenario {
            duration_s: 3.0,
            ..Scenario::paper_case(2, 1, None, None)
        };
        scn.perturbations.window_s = [1.0, 2.0];
        let runs: Vec<SimOutput> = ControllerKind::ALL
            .iter()
            .map(|&k| crate::sim::run(&scn, k).unwrap())
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let files = write_case_plots(dir.path(), "case2", "Case 2", &scn, &runs).unwrap();
        // The governor is on: its pacing figure comes in addition.
        assert_eq!(files.len(), 2 * (FIGURES.len() + 1));
        assert!(dir.path().join("case2_pacing.png").is_file());
        let printed = scn.clone().as_printed();
        let files = write_case_plots(dir.path(), "paper", "Case 2", &printed, &runs).unwrap();
        assert_eq!(files.len(), 2 * FIGURES.len());
        for f in &files {
            let len = std::fs::metadata(f).unwrap().len();
            assert!(len > 5_000, "{} is only {len} bytes", f.display());
        }
        assert!(dir.path().join("case2_faults.svg").is_file());
    }
}
