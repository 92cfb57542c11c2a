//! The optimisers a tuning job can use, from maintained crates (D93):
//! CMA-ES (`cmaes`, the default), Nelder-Mead and particle swarm
//! (`argmin`). Each minimises a cost over the unit box of
//! [`super::space`] with a budget of cost evaluations; all three see the
//! same wrapper ([`Objective`]), which clamps a point into the box, adds
//! [`super::space::box_penalty`], counts evaluations and keeps the best
//! point seen.
//!
//! Determinism: CMA-ES draws its whole generation from its own seeded
//! generator before evaluating it (in parallel, results in sample order);
//! the swarm draws from a seeded xoshiro generator and evaluates its
//! particles in bulk (results in particle order); Nelder-Mead evaluates
//! one point at a time. The best point is the smallest cost with ties
//! broken by the point's coordinates, so neither the thread count nor the
//! order in which parallel evaluations finish changes a result.

use super::space::box_penalty;
use serde::{Deserialize, Serialize};
use std::sync::Mutex;

/// Population of CMA-ES and the swarm's particle count: the same for
/// every controller, so equal budgets mean equal generations.
pub const POPULATION: usize = 10;
/// CMA-ES's initial step size and Nelder-Mead's initial simplex edge, in
/// unit-box coordinates.
pub const INITIAL_STEP: f64 = 0.15;

/// Which optimiser.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Optimizer {
    /// CMA-ES (crate `cmaes`), population [`POPULATION`].
    #[default]
    Cmaes,
    /// Nelder-Mead (crate `argmin`) from a simplex around the start.
    NelderMead,
    /// Particle swarm (crate `argmin`), [`POPULATION`] particles.
    Pso,
}

impl Optimizer {
    /// Name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Cmaes => "cmaes",
            Self::NelderMead => "nelder-mead",
            Self::Pso => "pso",
        }
    }
}

/// The best point an optimiser found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptResult {
    /// Unit-box coordinates (clamped into the box).
    pub x: Vec<f64>,
    /// Its cost.
    pub cost: f64,
    /// Cost evaluations spent.
    pub evaluations: usize,
    /// Best cost after each evaluation batch: (evaluations, best).
    pub history: Vec<(usize, f64)>,
}

/// The cost wrapper every optimiser calls.
pub struct Objective<'a> {
    f: &'a (dyn Fn(&[f64]) -> f64 + Sync),
    budget: usize,
    state: Mutex<State>,
}

struct State {
    evals: usize,
    best: Option<(f64, Vec<f64>)>,
}

/// Cost returned once the budget is spent (Nelder-Mead only; never best).
const OVER_BUDGET: f64 = f64::MAX / 4.0;

impl<'a> Objective<'a> {
    /// `f` on the unit box, at most `budget` evaluations.
    pub fn new(f: &'a (dyn Fn(&[f64]) -> f64 + Sync), budget: usize) -> Self {
        Self {
            f,
            budget,
            state: Mutex::new(State {
                evals: 0,
                best: None,
            }),
        }
    }

    /// The cost of `x`: f at `x` clamped into the box plus the box penalty.
    pub fn eval(&self, x: &[f64]) -> f64 {
        {
            let mut s = self.state.lock().expect("objective state");
            if s.evals >= self.budget {
                return OVER_BUDGET;
            }
            s.evals += 1;
        }
        let clamped: Vec<f64> = x
            .iter()
            .map(|&v| {
                if v.is_finite() {
                    v.clamp(0.0, 1.0)
                } else {
                    0.5
                }
            })
            .collect();
        let c = (self.f)(&clamped);
        let c = if c.is_nan() { OVER_BUDGET } else { c } + box_penalty(x);
        let mut s = self.state.lock().expect("objective state");
        let better = match &s.best {
            None => true,
            Some((bc, bx)) => c < *bc || (c == *bc && clamped.as_slice() < bx.as_slice()),
        };
        if better {
            s.best = Some((c, clamped));
        }
        c
    }

    fn best(&self) -> (f64, Vec<f64>, usize) {
        let s = self.state.lock().expect("objective state");
        let (c, x) = s.best.clone().unwrap_or((f64::INFINITY, Vec::new()));
        (c, x, s.evals)
    }
}

/// Minimises `f` over the unit box from `x0` with `budget` evaluations
/// (CMA-ES and the swarm use whole generations: `budget` rounded down to a
/// multiple of [`POPULATION`], at least one); `batch_done` is called after
/// each generation (or Nelder-Mead iteration) with (evaluations, best).
/// `x0_cost`, when given, is `f(x0)` already evaluated: `x0` is then a
/// candidate like any evaluated point (not counted in the budget), so the
/// result is never worse than the start (issue 34).
pub fn minimise(
    opt: Optimizer,
    f: &(dyn Fn(&[f64]) -> f64 + Sync),
    x0: &[f64],
    x0_cost: Option<f64>,
    budget: usize,
    seed: u64,
    batch_done: &(dyn Fn(usize, f64) + Sync),
) -> Result<OptResult, String> {
    let n = x0.len();
    let gens = (budget / POPULATION).max(1);
    let budget = match opt {
        Optimizer::NelderMead => budget.max(n + 1),
        _ => gens * POPULATION,
    };
    let obj = Objective::new(f, budget);
    if let Some(c) = x0_cost {
        let x: Vec<f64> = x0.iter().map(|v| v.clamp(0.0, 1.0)).collect();
        let c = if c.is_nan() { OVER_BUDGET } else { c } + box_penalty(x0);
        obj.state.lock().expect("objective state").best = Some((c, x));
    }
    let mut history = Vec::new();
    match opt {
        Optimizer::Cmaes => {
            use cmaes::{CMAESOptions, DVector};
            let func = |x: &DVector<f64>| obj.eval(x.as_slice());
            let mut cma = CMAESOptions::new(x0.to_vec(), INITIAL_STEP)
                .population_size(POPULATION)
                .max_generations(gens)
                .seed(seed)
                .build(func)
                .map_err(|e| format!("CMA-ES options: {e:?}"))?;
            loop {
                let done = cma.next_parallel();
                let (c, _, e) = obj.best();
                history.push((e, c));
                batch_done(e, c);
                if done.is_some() {
                    break;
                }
            }
        }
        Optimizer::NelderMead => {
            use argmin::core::{CostFunction, Error, Executor, State as _};
            use argmin::solver::neldermead::NelderMead;
            struct P<'o, 'a>(&'o Objective<'a>);
            impl CostFunction for P<'_, '_> {
                type Param = Vec<f64>;
                type Output = f64;
                fn cost(&self, x: &Vec<f64>) -> Result<f64, Error> {
                    Ok(self.0.eval(x))
                }
            }
            let mut simplex = vec![x0.to_vec()];
            for i in 0..n {
                let mut v = x0.to_vec();
                v[i] += if v[i] + INITIAL_STEP <= 1.0 {
                    INITIAL_STEP
                } else {
                    -INITIAL_STEP
                };
                simplex.push(v);
            }
            let solver = NelderMead::new(simplex)
                .with_sd_tolerance(1e-9)
                .map_err(|e| e.to_string())?;
            let res = Executor::new(P(&obj), solver)
                .configure(|s| s.max_iters(budget as u64))
                .run()
                .map_err(|e| format!("Nelder-Mead: {e}"))?;
            let _ = res.state().get_iter();
            let (c, _, e) = obj.best();
            history.push((e, c));
            batch_done(e, c);
        }
        Optimizer::Pso => {
            use argmin::core::{CostFunction, Error, Executor};
            use argmin::solver::particleswarm::ParticleSwarm;
            use rand_xoshiro::rand_core::SeedableRng;
            struct P<'o, 'a>(&'o Objective<'a>);
            impl CostFunction for P<'_, '_> {
                type Param = Vec<f64>;
                type Output = f64;
                fn cost(&self, x: &Vec<f64>) -> Result<f64, Error> {
                    Ok(self.0.eval(x))
                }
            }
            let solver = ParticleSwarm::new((vec![0.0; n], vec![1.0; n]), POPULATION)
                .with_rng_generator(rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed));
            Executor::new(P(&obj), solver)
                .configure(|s| s.max_iters(gens as u64 - 1))
                .run()
                .map_err(|e| format!("particle swarm: {e}"))?;
            let (c, _, e) = obj.best();
            history.push((e, c));
            batch_done(e, c);
        }
    }
    let (cost, x, evaluations) = obj.best();
    if x.is_empty() {
        return Err("the optimiser evaluated nothing".into());
    }
    Ok(OptResult {
        x,
        cost,
        evaluations,
        history,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shifted sphere with its minimum 0 at (0.3, 0.7, 0.5, 0.2).
    fn sphere(x: &[f64]) -> f64 {
        let c = [0.3, 0.7, 0.5, 0.2];
        x.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum()
    }

    #[test]
    fn each_optimiser_improves_on_the_start_within_its_budget() {
        let x0 = [0.9; 4];
        for opt in [Optimizer::Cmaes, Optimizer::NelderMead, Optimizer::Pso] {
            let r = minimise(opt, &sphere, &x0, None, 300, 7, &|_, _| {}).unwrap();
            assert!(r.evaluations <= 300, "{opt:?}: {}", r.evaluations);
            assert!(r.cost < 0.01 * sphere(&x0), "{opt:?}: {}", r.cost);
            assert!((sphere(&r.x) - r.cost).abs() < 1e-12);
        }
    }

    #[test]
    fn a_start_no_evaluation_can_beat_is_the_result() {
        // The start is the sphere's minimum: every point the optimiser
        // tries costs more, so the start (given with its cost) is returned.
        let x0 = [0.3, 0.7, 0.5, 0.2];
        for opt in [Optimizer::Cmaes, Optimizer::NelderMead, Optimizer::Pso] {
            let r = minimise(opt, &sphere, &x0, Some(0.0), 50, 7, &|_, _| {}).unwrap();
            assert_eq!(r.x, x0.to_vec(), "{opt:?}");
            assert_eq!(r.cost, 0.0);
            // Without it CMA-ES and the swarm return a point they drew
            // (Nelder-Mead's simplex holds the start as a vertex).
            if opt != Optimizer::NelderMead {
                let r = minimise(opt, &sphere, &x0, None, 50, 7, &|_, _| {}).unwrap();
                assert!(r.cost > 0.0, "{opt:?}");
            }
        }
    }

    #[test]
    fn same_seed_same_result_on_any_thread_count() {
        for opt in [Optimizer::Cmaes, Optimizer::Pso] {
            let run = |threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| {
                        minimise(opt, &sphere, &[0.9; 4], None, 100, 3, &|_, _| {}).unwrap()
                    })
            };
            assert_eq!(run(1), run(3), "{opt:?}");
        }
    }
}
