//! `wmr params get|set`: the robot's live parameters by name.

use crate::link::{Link, LinkError};
use crate::session;
use clap::{Args, Subcommand};
use std::io::Write;
use wmr_protocol::{ParamId, Reply, Request};

/// `params` options.
#[derive(Debug, Args)]
pub struct ParamsArgs {
    /// get or set.
    #[command(subcommand)]
    pub op: ParamsOp,
}

/// `params` operations.
#[derive(Debug, Subcommand)]
pub enum ParamsOp {
    /// Print one parameter, or all.
    Get {
        /// Parameter name (docs/protocol.md); all when omitted.
        name: Option<String>,
    },
    /// Write one parameter.
    Set {
        /// Parameter name.
        name: String,
        /// Value in the parameter's unit.
        #[arg(allow_hyphen_values = true)]
        value: f32,
    },
}

fn param_id(name: &str) -> Result<ParamId, LinkError> {
    ParamId::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = ParamId::ALL.iter().map(|p| p.name()).collect();
        LinkError::Io(format!(
            "unknown parameter {name:?} (one of: {})",
            names.join(", ")
        ))
    })
}

/// `params get|set`.
pub fn params(op: &ParamsOp, link: &mut Link, out: &mut dyn Write) -> Result<(), LinkError> {
    match op {
        ParamsOp::Get { name } => {
            let ids = match name {
                Some(n) => vec![param_id(n)?],
                None => ParamId::ALL.to_vec(),
            };
            for id in ids {
                match link.command(&Request::GetParam(id))? {
                    Reply::Param { value, .. } => {
                        writeln!(out, "{} = {value}", id.name()).map_err(session::io)?
                    }
                    r => return Err(LinkError::Unexpected(format!("{r:?}"))),
                }
            }
        }
        ParamsOp::Set { name, value } => {
            let id = param_id(name)?;
            link.command(&Request::SetParam { id, value: *value })
                .map_err(|e| match e {
                    LinkError::Nack(_, c) => LinkError::Nack(format!("{name} = {value}"), c),
                    e => e,
                })?;
            writeln!(out, "{name} = {value}").map_err(session::io)?;
        }
    }
    Ok(())
}
