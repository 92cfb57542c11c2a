//! The TOML text form and the JSON schema (host side, `std` feature).

use crate::error::RobotError;
use crate::sections::{Robot, FORMAT};
use std::format;
use std::string::{String, ToString};
use std::vec::Vec;

/// A robot file refused by [`Robot::from_toml_str`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum RobotFileError {
    /// Not TOML, a missing field, an unknown key or a wrong type.
    Toml {
        /// TOML path of the field, when it could be told.
        field: Option<String>,
        /// 1-based line.
        line: Option<usize>,
        /// The parser's message.
        message: String,
    },
    /// `format` is not the version this build reads.
    UnsupportedFormat {
        /// What the file says.
        found: i64,
    },
    /// Well-formed, but [`Robot::validate`] refuses it.
    Invalid {
        /// The field and why.
        error: RobotError,
        /// 1-based line of the field in the file, when it is there.
        line: Option<usize>,
    },
}

impl RobotFileError {
    /// TOML path of the field at fault, when known.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::Toml { field, .. } => field.as_deref(),
            Self::UnsupportedFormat { .. } => Some("format"),
            Self::Invalid { error, .. } => Some(error.field),
        }
    }
}

impl core::fmt::Display for RobotFileError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Toml {
                field,
                line,
                message,
            } => {
                if let Some(l) = line {
                    write!(f, "line {l}: ")?;
                }
                if let Some(p) = field {
                    write!(f, "{p}: ")?;
                }
                write!(f, "{}", message.trim_end())
            }
            Self::UnsupportedFormat { found } => write!(
                f,
                "format: this file is format {found}, this build reads format {FORMAT}"
            ),
            Self::Invalid { error, line } => {
                if let Some(l) = line {
                    write!(f, "line {l}: ")?;
                }
                write!(f, "{error}")
            }
        }
    }
}

impl std::error::Error for RobotFileError {}

fn line_at(text: &str, byte: usize) -> usize {
    text[..byte.min(text.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

/// The table header (`body`, `gains.smc.sliding`) in force at 1-based `line`.
fn table_at(text: &str, line: usize) -> String {
    let mut table = String::new();
    for l in text.lines().take(line) {
        let t = l.trim();
        if t.starts_with('[') {
            table = t.trim_matches(|c| c == '[' || c == ']').trim().to_string();
        }
    }
    table
}

fn join(table: &str, key: &str) -> String {
    if table.is_empty() {
        key.to_string()
    } else {
        format!("{table}.{key}")
    }
}

fn backticked(message: &str) -> Option<&str> {
    let a = message.find('`')?;
    let b = message[a + 1..].find('`')?;
    Some(&message[a + 1..a + 1 + b])
}

/// Every leaf field path of a robot file with every gain section present
/// ([`crate::FIELDS`], then [`crate::GAIN_FIELDS`] under each controller,
/// the fixed switching gain for SMC and the adaptive one for the others,
/// as [`GainSet::paper`](crate::GainSet::paper) has them).
pub fn field_paths() -> Vec<String> {
    let mut v: Vec<String> = crate::FIELDS.iter().map(|s| s.to_string()).collect();
    for kind in ["proposed", "smc", "asmc"] {
        for g in crate::GAIN_FIELDS {
            let fixed = g.contains("switching.fixed");
            let adaptive = g.contains("switching.adaptive");
            if (kind == "smc" && adaptive) || (kind != "smc" && fixed) {
                continue;
            }
            v.push(format!("gains.{kind}.{g}"));
        }
    }
    v
}

/// Every fixed-size array of a robot file must have exactly its length:
/// serde's arrays stop reading after their N elements and the TOML reader
/// let the rest pass (`wheel_radius_m = [0.1, 0.1, "junk", {a = 1}]` was
/// accepted, issue 31 item 4). The lengths come from [`field_paths`]
/// (`body.wheel_radius_m[1]`: two elements).
fn check_array_lengths(doc: &toml::Table, text: &str) -> Result<(), RobotFileError> {
    let mut lengths: std::collections::BTreeMap<String, usize> = Default::default();
    for p in field_paths() {
        if let Some((base, rest)) = p.split_once('[') {
            let i: usize = rest.trim_end_matches(']').parse().unwrap_or(0);
            let n = lengths.entry(base.to_string()).or_insert(0);
            *n = (*n).max(i + 1);
        }
    }
    for (path, n) in lengths {
        let mut cur = Some(doc);
        let parts: Vec<&str> = path.split('.').collect();
        let mut value = None;
        for (i, part) in parts.iter().enumerate() {
            match cur.and_then(|t| t.get(*part)) {
                Some(toml::Value::Table(t)) if i + 1 < parts.len() => cur = Some(t),
                Some(v) if i + 1 == parts.len() => value = Some(v),
                _ => break,
            }
        }
        if let Some(toml::Value::Array(a)) = value {
            if a.len() != n {
                return Err(RobotFileError::Toml {
                    line: line_of(text, &path),
                    message: format!(
                        "{path} has {} elements; it takes exactly {n} (remove the others)",
                        a.len()
                    ),
                    field: Some(path),
                });
            }
        }
    }
    Ok(())
}

fn present(doc: &toml::Table, path: &str) -> bool {
    let mut cur = doc;
    let parts: Vec<&str> = path.split('.').collect();
    for (i, p) in parts.iter().enumerate() {
        match cur.get(*p) {
            Some(toml::Value::Table(t)) if i + 1 < parts.len() => cur = t,
            Some(_) if i + 1 == parts.len() => return true,
            _ => return false,
        }
    }
    false
}

/// The path of a missing field `key` at or below table `table`: the schema's
/// field of that name whose parent exists in the file and which is absent.
fn missing_path(doc: Option<&toml::Table>, table: &str, key: &str) -> Option<String> {
    let doc = doc?;
    let mut best: Option<String> = None;
    for p in field_paths() {
        let p = p.split('[').next().unwrap_or(&p).to_string();
        let (parent, k) = match p.rsplit_once('.') {
            Some((a, b)) => (a.to_string(), b),
            None => (String::new(), p.as_str()),
        };
        let related = table.starts_with(parent.as_str()) || parent.starts_with(table);
        if k == key
            && related
            && !present(doc, &p)
            && (parent.is_empty() || present_table(doc, &parent))
        {
            best = Some(p.clone());
        }
    }
    best
}

fn present_table(doc: &toml::Table, path: &str) -> bool {
    let mut cur = doc;
    for p in path.split('.') {
        match cur.get(p) {
            Some(toml::Value::Table(t)) => cur = t,
            _ => return false,
        }
    }
    true
}

fn toml_error(text: &str, e: &toml::de::Error) -> RobotFileError {
    let doc: Option<toml::Table> = text.parse().ok();
    let mut message = e.message().to_string();
    if message.contains("wanted exactly 1 element") {
        message = "an enum table takes exactly one key, the variant (`fixed` or `adaptive`)".into();
    }
    let line = e.span().map(|s| line_at(text, s.start));
    let field = line.map(|l| {
        let table = table_at(text, l);
        let this = text.lines().nth(l - 1).unwrap_or("").trim();
        if message.starts_with("missing field") || message.starts_with("unknown field") {
            match backticked(&message) {
                Some(k) => {
                    // A key on this line (`unknown field`) or the table the
                    // span covers (`missing field`).
                    let t = if this.starts_with('[') {
                        this.trim_matches(|c| c == '[' || c == ']')
                            .trim()
                            .to_string()
                    } else {
                        table.clone()
                    };
                    if message.starts_with("missing field") {
                        missing_path(doc.as_ref(), &t, k).unwrap_or_else(|| join(&t, k))
                    } else {
                        join(&t, k)
                    }
                }
                None => table,
            }
        } else if let Some((k, _)) = this.split_once('=').filter(|(k, _)| is_bare_key(k.trim())) {
            join(&table, k.trim())
        } else {
            // A comment (a carriage return or form feed inside one is a
            // TOML error on its line, issue 31 item 6: its text became the
            // field's name) or no key: the table.
            table
        }
    });
    RobotFileError::Toml {
        field,
        line,
        message,
    }
}

/// A key as a robot file writes it: letters, digits, `_` and `-` (a TOML
/// bare key), nothing else (no comment, no control character).
fn is_bare_key(k: &str) -> bool {
    !k.is_empty()
        && k.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// 1-based line of the field at TOML path `path` (`"body.wheel_radius_m[1]"`)
/// in `text`, when it is written as `key = ...` under its table.
fn line_of(text: &str, path: &str) -> Option<usize> {
    let path = path.split('[').next().unwrap_or(path);
    let (table, key) = match path.rsplit_once('.') {
        Some((t, k)) => (t, k),
        None => ("", path),
    };
    let mut current = String::new();
    let mut table_line = None;
    for (i, l) in text.lines().enumerate() {
        let t = l.trim();
        if t.starts_with('[') {
            current = t.trim_matches(|c| c == '[' || c == ']').trim().to_string();
            if current == table {
                table_line = Some(i + 1);
            }
            continue;
        }
        if current == table {
            if let Some((k, _)) = t.split_once('=') {
                if k.trim() == key {
                    return Some(i + 1);
                }
            }
        }
    }
    table_line
}

/// Replaces every float by the f64 nearest the shortest decimal of its f32
/// (0.1f32 is written `0.1`, not `0.10000000149011612`); reading it back as
/// f32 gives the same f32.
fn shorten_floats(v: &mut toml::Value) {
    match v {
        toml::Value::Float(x) => {
            let s = format!("{}", *x as f32);
            *x = s.parse().unwrap_or(*x);
        }
        toml::Value::Array(a) => a.iter_mut().for_each(shorten_floats),
        toml::Value::Table(t) => t.iter_mut().for_each(|(_, v)| shorten_floats(v)),
        _ => {}
    }
}

impl Robot {
    /// Reads a robot file: TOML, every field present, no unknown key, then
    /// [`Robot::validate`]. Errors name the field and the line.
    pub fn from_toml_str(text: &str) -> Result<Robot, RobotFileError> {
        let table: toml::Table = text.parse().map_err(|e| toml_error(text, &e))?;
        if let Some(toml::Value::Integer(found)) = table.get("format") {
            if *found != FORMAT as i64 {
                return Err(RobotFileError::UnsupportedFormat { found: *found });
            }
        }
        check_array_lengths(&table, text)?;
        let robot: Robot = toml::from_str(text).map_err(|e| toml_error(text, &e))?;
        robot.validate().map_err(|error| RobotFileError::Invalid {
            error,
            line: line_of(text, error.field),
        })?;
        Ok(robot)
    }

    /// The robot as a robot file ([`Robot::from_toml_str`] reads it back
    /// to the same robot).
    pub fn to_toml_string(&self) -> String {
        let mut v = toml::Value::try_from(self).expect("a Robot is a TOML table");
        shorten_floats(&mut v);
        // Absent gain sections are the paper's: no empty `[gains]` table;
        // a `[control]` with the defaults is left out (files written before
        // the section existed read back the same, D139).
        if let toml::Value::Table(t) = &mut v {
            if matches!(t.get("gains"), Some(toml::Value::Table(g)) if g.is_empty()) {
                t.remove("gains");
            }
            if self.control == crate::Control::default() {
                t.remove("control");
            }
            if self.estimator == crate::Estimator::default() {
                t.remove("estimator");
            }
        }
        toml::to_string(&v).expect("a TOML value serializes")
    }
}

/// The JSON schema of the robot file, pretty-printed (committed as
/// `robots/robot.schema.json`; regenerate with
/// `cargo run -p robot-file --example schema > robots/robot.schema.json`).
pub fn json_schema() -> String {
    let schema = schemars::schema_for!(Robot);
    let mut s = serde_json::to_string_pretty(&schema).expect("a schema serializes");
    s.push('\n');
    s
}
