//! book/src/reference/protocol.md's generated parts, from wmr-protocol's
//! types: the constants, every message type's wire layout (traced through
//! serde by serde-reflection: fields in wire order, variant indices), the
//! error codes and robot faults with their reasons, and the link's
//! parameters from the parameter table (issue 32, D144). The prose around
//! them is hand-written. `WMR_WRITE_REFERENCE=1 cargo test --release -p
//! wmr-protocol --test reference` rewrites them.

use serde_reflection::{
    ContainerFormat, Format, Named, Registry, Tracer, TracerConfig, VariantFormat,
};
use std::fmt::Write as _;
use std::path::Path;
use wmr_protocol::*;

#[path = "../../wmr/src/reference_check.rs"]
mod reference_check;

const PAGE: &str = "book/src/reference/protocol.md";
const COMMAND: &str = "WMR_WRITE_REFERENCE=1 cargo test --release -p wmr-protocol --test reference";

/// Every type of the link, traced from the two messages.
fn registry() -> Registry {
    let mut tracer = Tracer::new(TracerConfig::default());
    tracer
        .trace_simple_type::<Request>()
        .expect("Request traces");
    tracer.trace_simple_type::<Reply>().expect("Reply traces");
    // serde-reflection finds an enum's other variants only when it traces
    // the enum itself: each enum inside the messages (`registry` fails
    // naming one left out).
    macro_rules! enums {
        ($($t:ty),*) => {$(tracer.trace_simple_type::<$t>().expect(stringify!($t));)*};
    }
    enums!(
        BuiltinShape,
        ErrorCode,
        Event,
        ModeMsg,
        ParamId,
        ResetCause,
        RobotFaultKind,
        RobotSource,
        RunStateMsg,
        StopCode,
        WheelTestEnd
    );
    tracer
        .registry()
        .expect("every variant of every enum traced")
}

/// The unit a field's name carries (the project's `_m`, `_us`, ...
/// suffixes), or "–".
fn unit_of(field: &str) -> &'static str {
    const SUFFIXES: [(&str, &str); 14] = [
        ("_mps2", "m/s²"),
        ("_radps2", "rad/s²"),
        ("_mps", "m/s"),
        ("_radps", "rad/s"),
        ("_rad", "rad"),
        ("_us", "µs"),
        ("_ms", "ms"),
        ("_s", "s"),
        ("_hz", "Hz"),
        ("_nm", "N·m"),
        ("_kg", "kg"),
        ("_m", "m"),
        ("_deg", "°"),
        ("_deg2", "deg²"),
    ];
    SUFFIXES
        .iter()
        .find(|(s, _)| field.ends_with(s))
        .map_or("–", |(_, u)| u)
}

fn ty(f: &Format) -> String {
    match f {
        Format::TypeName(n) => format!("[`{n}`](#type-{})", n.to_lowercase()),
        Format::Unit => "()".into(),
        Format::Bool => "bool".into(),
        Format::I8 => "i8".into(),
        Format::I16 => "i16".into(),
        Format::I32 => "i32".into(),
        Format::I64 => "i64".into(),
        Format::I128 => "i128".into(),
        Format::U8 => "u8".into(),
        Format::U16 => "u16".into(),
        Format::U32 => "u32".into(),
        Format::U64 => "u64".into(),
        Format::U128 => "u128".into(),
        Format::F32 => "f32".into(),
        Format::F64 => "f64".into(),
        Format::Char => "char".into(),
        Format::Str => "string".into(),
        Format::Bytes => "bytes".into(),
        Format::Option(x) => format!("Option&lt;{}&gt;", ty(x)),
        Format::Seq(x) => format!("sequence of {}", ty(x)),
        Format::Map { key, value } => format!("map {} → {}", ty(key), ty(value)),
        Format::Tuple(xs) => format!("({})", xs.iter().map(ty).collect::<Vec<_>>().join(", ")),
        Format::TupleArray { content, size } => format!("[{}; {size}]", ty(content)),
        Format::Variable(_) => "?".into(),
    }
}

fn fields(fs: &[Named<Format>]) -> String {
    fs.iter()
        .map(|f| match unit_of(&f.name) {
            "–" => format!("`{}`: {}", f.name, ty(&f.value)),
            u => format!("`{}`: {} ({u})", f.name, ty(&f.value)),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The wire layout of every type, `Request` and `Reply` first.
fn layout(reg: &Registry) -> String {
    let mut out = String::new();
    let mut names: Vec<&String> = reg.keys().collect();
    names.sort_by_key(|n| (*n != "Request", *n != "Reply", n.to_string()));
    let links: Vec<String> = names
        .iter()
        .map(|n| format!("[`{n}`](#type-{})", n.to_lowercase()))
        .collect();
    let _ = writeln!(
        out,
        "{}

{}",
        links[..2].join(" · "),
        links[2..].join(" · ")
    );
    for n in names {
        let _ = write!(out, "\n#### type `{n}`\n\n");
        match &reg[n] {
            ContainerFormat::UnitStruct => out.push_str("No fields (nothing on the wire).\n"),
            ContainerFormat::NewTypeStruct(f) => {
                let _ = writeln!(out, "Encoded as {}.", ty(f));
            }
            ContainerFormat::TupleStruct(fs) => {
                let t: Vec<String> = fs.iter().map(ty).collect();
                let _ = writeln!(out, "Encoded as the tuple ({}).", t.join(", "));
            }
            ContainerFormat::Struct(fs) => {
                out.push_str("| field | type | unit |\n|---|---|---|\n");
                for f in fs {
                    let _ = writeln!(
                        out,
                        "| `{}` | {} | {} |",
                        f.name,
                        ty(&f.value),
                        unit_of(&f.name)
                    );
                }
            }
            ContainerFormat::Enum(vs) => {
                out.push_str("| index | variant | fields |\n|---|---|---|\n");
                for (i, v) in vs {
                    let body = match &v.value {
                        VariantFormat::Unit => "–".to_string(),
                        VariantFormat::NewType(f) => ty(f),
                        VariantFormat::Tuple(fs) => {
                            fs.iter().map(ty).collect::<Vec<_>>().join(", ")
                        }
                        VariantFormat::Struct(fs) => fields(fs),
                        VariantFormat::Variable(_) => "?".into(),
                    };
                    let _ = writeln!(out, "| {i} | `{n}::{}` | {body} |", v.name);
                }
            }
        }
    }
    out
}

/// The protocol's constants: name, value, meaning.
fn constants() -> String {
    let rows: [(&str, u64, &str); 19] = [
        (
            "PROTOCOL_VERSION",
            PROTOCOL_VERSION.into(),
            "in every envelope",
        ),
        ("MAX_BODY", MAX_BODY as u64, "largest body [bytes]"),
        (
            "MAX_FRAME",
            MAX_FRAME as u64,
            "largest frame, delimiter included [bytes]",
        ),
        (
            "SEGMENT_POINTS",
            SEGMENT_POINTS as u64,
            "waypoints per `Request::TrajectorySegment`",
        ),
        (
            "ROBOT_BLOB_MAX",
            ROBOT_BLOB_MAX as u64,
            "largest robot record [bytes]",
        ),
        (
            "ROBOT_CHUNK",
            ROBOT_CHUNK as u64,
            "robot record bytes per chunk",
        ),
        (
            "ROBOT_FIELD_LEN",
            ROBOT_FIELD_LEN as u64,
            "longest field path in a `RobotFault` [bytes]",
        ),
        (
            "WHEEL_TEST_MAX_MS",
            WHEEL_TEST_MAX_MS.into(),
            "longest wheel test [ms]",
        ),
        (
            "CAP_EXTERNAL_POSE",
            CAP_EXTERNAL_POSE.into(),
            "capability bit: external poses",
        ),
        (
            "CAP_TRAJECTORY",
            CAP_TRAJECTORY.into(),
            "capability bit: waypoint trajectories",
        ),
        (
            "CAP_VELOCITY",
            CAP_VELOCITY.into(),
            "capability bit: velocity commands",
        ),
        (
            "CAP_SIMULATED",
            CAP_SIMULATED.into(),
            "capability bit: a simulated robot",
        ),
        (
            "CAP_ROBOT_STORE",
            CAP_ROBOT_STORE.into(),
            "capability bit: a robot store",
        ),
        (
            "TELEMETRY_TRACKING",
            TELEMETRY_TRACKING.into(),
            "telemetry group bit",
        ),
        (
            "TELEMETRY_ESTIMATORS",
            TELEMETRY_ESTIMATORS.into(),
            "telemetry group bit",
        ),
        (
            "TELEMETRY_COUNTERS",
            TELEMETRY_COUNTERS.into(),
            "telemetry group bit",
        ),
        (
            "TELEMETRY_COVARIANCE",
            TELEMETRY_COVARIANCE.into(),
            "telemetry group bit",
        ),
        (
            "TELEMETRY_ALL",
            TELEMETRY_ALL.into(),
            "every telemetry group",
        ),
        (
            "ParamId::ALL.len()",
            ParamId::ALL.len() as u64,
            "parameters on the link",
        ),
    ];
    let mut out = String::from("| constant | value | what |\n|---|---|---|\n");
    for (n, v, what) in rows {
        let _ = writeln!(out, "| `{n}` | {v} | {what} |");
    }
    out
}

/// `ErrorCode` and `RobotFaultKind` with their indices and the reasons
/// `wmr` prints.
fn reasons(reg: &Registry, name: &str, reason: impl Fn(u32) -> &'static str) -> String {
    let ContainerFormat::Enum(vs) = &reg[name] else {
        panic!("{name} is an enum")
    };
    let mut out = String::from("| index | code | reason (as `wmr` prints it) |\n|---|---|---|\n");
    for (i, v) in vs {
        let _ = writeln!(out, "| {i} | `{name}::{}` | {} |", v.name, reason(*i));
    }
    out
}

/// The variant of `T` at wire index `i`.
fn at<T: serde::de::DeserializeOwned>(i: u32) -> T {
    let mut bytes = [0u8; 16];
    bytes[0] = u8::try_from(i).expect("a one-byte varint index");
    postcard::from_bytes(&bytes).expect("a unit variant")
}

/// The link's parameters from the parameter table.
fn params() -> String {
    let mut t = String::from(
        "| id | `ParamId` | name | unit | write | range | was |\n|---|---|---|---|---|---|---|\n",
    );
    for (i, id) in ParamId::ALL.into_iter().enumerate() {
        let p = id.param();
        let mut range = String::new();
        p.write_range(&mut range).unwrap();
        let unit = if p.unit.is_empty() { "–" } else { p.unit };
        let was = p.old_name.map_or("–".into(), |o| format!("`{o}`"));
        let _ = writeln!(
            t,
            "| {i} | `ParamId::{id:?}` | `{}` | {unit} | {} | {range} | {was} |",
            p.name,
            p.access.describe()
        );
    }
    t
}

/// Replaces the text between `<!-- NAME begin ... -->` and `<!-- NAME end -->`.
fn fill(doc: &str, name: &str, body: &str) -> String {
    let begin = format!(
        "<!-- {name} begin: generated by wmr-protocol/tests/reference.rs, do not edit -->\n"
    );
    let end = format!("<!-- {name} end -->");
    let (head, rest) = doc
        .split_once(&begin)
        .unwrap_or_else(|| panic!("{PAGE}: no `{}` marker", begin.trim_end()));
    let (_, tail) = rest
        .split_once(&end)
        .unwrap_or_else(|| panic!("{PAGE}: no `{end}` marker"));
    format!("{head}{begin}{body}{end}{tail}")
}

#[test]
fn the_protocol_reference_is_the_types() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(PAGE);
    let doc = std::fs::read_to_string(&path).expect(PAGE);
    let reg = registry();
    let mut want = fill(&doc, "constants", &constants());
    want = fill(&want, "wire-layout", &layout(&reg));
    want = fill(
        &want,
        "error-codes",
        &reasons(&reg, "ErrorCode", |i| at::<ErrorCode>(i).reason()),
    );
    want = fill(
        &want,
        "robot-faults",
        &reasons(&reg, "RobotFaultKind", |i| at::<RobotFaultKind>(i).reason()),
    );
    want = fill(&want, "wire-params", &params());
    if let Err(e) = reference_check::check_or_write(&path, PAGE, &want, COMMAND) {
        panic!("{e}");
    }
}
