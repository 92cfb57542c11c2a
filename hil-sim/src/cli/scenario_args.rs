//! [`ScenarioArgs`]: the scenario flags shared by `run` and `device`. The
//! flags are [`Scenario`]'s own fields and its parts' (clap derives them from
//! the very structs serde reads scenario files into), read through
//! [`Flags`], which applies only the flags given on top of the file or the
//! preset: each knob is declared once.

use crate::scenario::Scenario;
use crate::scenario_file::load_scenario;
use clap::{ArgMatches, Args, FromArgMatches};
use std::marker::PhantomData;
use std::path::PathBuf;

/// The flags of `T` (a clap [`Args`] struct) as overrides: its arguments are
/// declared as for an update (none required), and the matches are kept, so
/// [`Flags::apply`] sets only the fields whose flag was given. `T` keeps
/// plain values (`f64`, not `Option<f64>`), its defaults in its `Default`.
#[derive(Debug, Default, Clone)]
pub struct Flags<T> {
    matches: ArgMatches,
    of: PhantomData<T>,
}

impl<T: Args + FromArgMatches> Flags<T> {
    /// Sets the fields of `target` whose flag was given.
    pub fn apply(&self, target: &mut T) -> Result<(), String> {
        target
            .update_from_arg_matches(&self.matches)
            .map_err(|e| e.to_string())
    }

    /// The value of the flag with id `id` (the field's name), if given.
    pub fn get<V: Clone + Send + Sync + 'static>(&self, id: &str) -> Option<V> {
        self.matches.try_get_one::<V>(id).ok().flatten().cloned()
    }
}

impl<T: Args> FromArgMatches for Flags<T> {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        Ok(Self {
            matches: matches.clone(),
            of: PhantomData,
        })
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        self.matches = matches.clone();
        Ok(())
    }
}

impl<T: Args> Args for Flags<T> {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        T::augment_args_for_update(cmd)
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        T::augment_args_for_update(cmd)
    }
}

/// Scenario selection and overrides shared by `run` and `device`.
#[derive(Debug, Args, Default, Clone)]
pub struct ScenarioArgs {
    /// Paper preset: 1 = disturbance + slip, 2 = + actuator fault [default:
    /// 2; `device --robot FILE`: none, the robot unperturbed].
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2), conflicts_with = "scenario")]
    pub case: Option<u8>,
    /// Scenario TOML file (schema: book/src/reference/scenario-file.md); the flags below override it.
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// The robot files (`--robot`, `--plant`).
    #[command(flatten)]
    pub robots: super::robot_arg::RobotArgs,
    /// Every knob of the scenario (book/src/reference/scenario-file.md): the fields of
    /// [`Scenario`] and of its parts.
    #[command(flatten)]
    pub flags: Flags<Scenario>,
}

impl ScenarioArgs {
    /// The scenario: the file or the paper preset (whose β, ε are drawn
    /// from `--seed`), then the flags given on top; validated.
    pub fn build(&self) -> Result<Scenario, String> {
        self.build_from(false)
    }

    /// [`Self::build`]; with `nominal`, the preset's perturbations are
    /// dropped before the flags apply (`hil-sim device --robot FILE`: the
    /// paper case's 1 N·m disturbance, slip and fault are for the paper's
    /// 15 kg robot; `--case`, a scenario file or the perturbation flags
    /// bring them back).
    pub fn build_from(&self, nominal: bool) -> Result<Scenario, String> {
        let mut scn = match &self.scenario {
            Some(path) => load_scenario(path)?,
            None => Scenario::paper_case(
                self.case.unwrap_or(2),
                self.flags.get::<u64>("seed").unwrap_or(1),
                None,
                None,
            ),
        };
        if nominal {
            scn.perturbations = crate::scenario::PerturbationPart::none();
        }
        let (robot, plant) = self.robots.load()?;
        scn = scn.with_robots(robot.as_ref(), plant.as_ref());
        self.flags.apply(&mut scn)?;
        scn.validate()?;
        Ok(scn)
    }
}
