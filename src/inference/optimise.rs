//! The optimisers (argmin's Nelder–Mead and particle swarm over the log parameters), the evaluation
//! cache and the budget.
//!
//! Every point the optimiser asks for is clamped into the bounds; the cache is keyed by the exact
//! bits of the clamped log point, so a repeated point costs nothing, and a trace read back from disk
//! pre-fills it (resumption). Batches (the swarm, the initial simplex, the profile) are evaluated in
//! parallel and recorded in request order, so the trace is the same whatever the thread count.
//!
//! Bounds: the swarm is bounded natively (argmin clamps particle positions). Nelder–Mead is
//! unbounded, so a point outside is evaluated at its clamped image and charged
//! [`BOUND_PENALTY`]·(log-distance moved)², which pushes the simplex back inside.

use super::InferenceError;
use super::config::{OptimizerConfig, OptimizerMethod};
use super::forward::{Evaluation, ForwardModel};
use crate::geometry::Real;
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::particleswarm::ParticleSwarm;
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::SeedableRng;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

/// Objective charged per squared log-unit a Nelder–Mead point lies outside the bounds.
pub const BOUND_PENALTY: Real = 100.0;

/// Why the evaluator refused a batch: the budget of distinct evaluations is spent (a normal way for
/// a fit to end), or the caller stopped the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum Halt {
    #[error("evaluation budget of {0} spent")]
    BudgetSpent(usize),
    #[error("stopped by the caller")]
    Stopped,
}

type Key = Vec<u64>;

/// Called after each batch with the whole trace so far.
pub type RecordHook<'a> = Box<dyn Fn(&[Evaluation]) + Send + Sync + 'a>;

fn key(x: &[Real]) -> Key {
    x.iter().map(|v| v.to_bits()).collect()
}

struct Store {
    /// Distinct evaluations in first-request order (the trace).
    trace: Vec<Evaluation>,
    index: HashMap<Key, usize>,
    /// Evaluations read from an earlier trace, not yet asked for again.
    preloaded: HashMap<Key, Evaluation>,
    /// Simulations actually run in this process.
    simulated: usize,
}

/// Runs evaluations for the optimisers: cache, budget, parallel batches, ordered trace.
pub struct Evaluator<'a> {
    model: &'a ForwardModel,
    budget: usize,
    store: Mutex<Store>,
    /// Called after each batch with the whole trace (writes trace.csv, updates progress).
    on_record: RecordHook<'a>,
    /// When this session began, and the fit's wall time before it (earlier sessions of a resumed fit):
    /// each new evaluation's `elapsed_seconds`.
    clock: (Instant, Real),
}

impl<'a> Evaluator<'a> {
    /// `preloaded`: the evaluations of a trace being resumed; the fit's wall time before this session
    /// is taken as the latest `elapsed_seconds` among them. `session`: when this session began.
    pub fn new(
        model: &'a ForwardModel,
        budget: usize,
        preloaded: Vec<Evaluation>,
        on_record: RecordHook<'a>,
        session: Instant,
    ) -> Self {
        let before = elapsed_before(&preloaded);
        let preloaded = preloaded.into_iter().map(|e| (key(&e.x), e)).collect();
        Self {
            model,
            budget,
            store: Mutex::new(Store { trace: Vec::new(), index: HashMap::new(), preloaded, simulated: 0 }),
            on_record,
            clock: (session, before),
        }
    }

    /// Seconds of the fit before this session (the earlier sessions of a resumed fit).
    pub fn earlier_seconds(&self) -> Real {
        self.clock.1
    }

    /// Seconds of the whole fit so far: the earlier sessions' (up to their last recorded evaluation)
    /// and this one's.
    pub fn elapsed_seconds(&self) -> Real {
        self.clock.1 + self.clock.0.elapsed().as_secs_f64()
    }

    pub fn model(&self) -> &ForwardModel {
        self.model
    }

    /// The trace so far.
    pub fn trace(&self) -> Vec<Evaluation> {
        self.store.lock().expect("evaluator lock").trace.clone()
    }

    /// Simulations run in this process (not read from a trace).
    pub fn simulated(&self) -> usize {
        self.store.lock().expect("evaluator lock").simulated
    }

    /// Evaluates a batch of log points (clamped first); results in order. With `charge_budget`
    /// false (the profile) the budget is not enforced. Errs with [`Halt::BudgetSpent`] when some point
    /// would exceed the budget (the points before it are evaluated and recorded), and with
    /// [`Halt::Stopped`] when the model's watch was stopped before or during a batch that needs new
    /// simulations (nothing of the batch is recorded then: an evaluation cut short is no evaluation);
    /// points already in the trace are still answered (argmin's Nelder–Mead panics on an error while
    /// it reads its initial simplex, which is always in the trace).
    pub fn evaluate_batch(&self, xs: &[Vec<Real>], charge_budget: bool) -> Result<Vec<Evaluation>, Halt> {
        let clamped: Vec<Vec<Real>> = xs.iter().map(|x| self.model.space.clamp(x).0).collect();
        let mut pending: Vec<Vec<Real>> = Vec::new();
        let mut pending_keys: HashMap<Key, usize> = HashMap::new();
        let mut spent = false;
        let mut accepted = clamped.len();
        {
            let mut store = self.store.lock().expect("evaluator lock");
            for (i, x) in clamped.iter().enumerate() {
                let k = key(x);
                if store.index.contains_key(&k) || pending_keys.contains_key(&k) {
                    continue;
                }
                if charge_budget && store.trace.len() >= self.budget {
                    spent = true;
                    accepted = i;
                    break;
                }
                if let Some(e) = store.preloaded.remove(&k) {
                    let n = store.trace.len();
                    store.trace.push(e);
                    store.index.insert(k, n);
                    continue;
                }
                // Reserve a trace slot so the budget counts pending points too.
                if charge_budget && store.trace.len() + pending.len() >= self.budget {
                    spent = true;
                    accepted = i;
                    break;
                }
                pending_keys.insert(k, pending.len());
                pending.push(x.clone());
            }
        }
        if !pending.is_empty() && self.model.watch.stopped() {
            return Err(Halt::Stopped);
        }
        let results: Vec<Evaluation> = pending.par_iter().map(|x| self.model.evaluate(x)).collect();
        if !pending.is_empty() && self.model.watch.stopped() {
            return Err(Halt::Stopped);
        }
        let out = {
            let mut store = self.store.lock().expect("evaluator lock");
            store.simulated += results.len();
            let now = self.elapsed_seconds();
            for mut e in results {
                e.elapsed_seconds = now;
                let n = store.trace.len();
                store.index.insert(key(&e.x), n);
                store.trace.push(e);
            }
            (self.on_record)(&store.trace);
            clamped[..accepted].iter().map(|x| store.trace[store.index[&key(x)]].clone()).collect()
        };
        if spent { Err(Halt::BudgetSpent(self.budget)) } else { Ok(out) }
    }

    /// Objective at `x` as Nelder–Mead sees it: the clamped point's objective plus the bound penalty.
    fn penalised(&self, xs: &[Vec<Real>]) -> Result<Vec<Real>, Halt> {
        let evals = self.evaluate_batch(xs, true)?;
        Ok(xs.iter().zip(evals).map(|(x, e)| e.objective + BOUND_PENALTY * self.model.space.clamp(x).1).collect())
    }
}

/// The evaluator as an argmin problem.
struct Problem<'e, 'a>(&'e Evaluator<'a>);

impl CostFunction for Problem<'_, '_> {
    type Param = Vec<Real>;
    type Output = Real;

    fn cost(&self, x: &Vec<Real>) -> Result<Real, ArgminError> {
        Ok(self.0.penalised(std::slice::from_ref(x))?[0])
    }

    fn bulk_cost<P>(&self, params: &[P]) -> Result<Vec<Real>, ArgminError>
    where
        P: std::borrow::Borrow<Vec<Real>> + Sync,
    {
        let xs: Vec<Vec<Real>> = params.iter().map(|p| p.borrow().clone()).collect();
        Ok(self.0.penalised(&xs)?)
    }
}

/// How the optimiser ended.
#[derive(Clone, Debug, PartialEq)]
pub struct OptimiserOutcome {
    /// The solver's own criterion was met (simplex spread or target objective).
    pub converged: bool,
    /// Why it stopped, in words.
    pub reason: String,
}

/// A Nelder–Mead simplex: `center` and one vertex per parameter, `fraction` of its log-range away
/// (inward when the start is in the upper part of the range).
fn initial_simplex(center: &[Real], fraction: Real, lo: &[Real], hi: &[Real]) -> Vec<Vec<Real>> {
    let mut simplex = vec![center.to_vec()];
    for i in 0..center.len() {
        let step = fraction * (hi[i] - lo[i]);
        let mut v = center.to_vec();
        v[i] = if center[i] + step <= hi[i] { center[i] + step } else { center[i] - step };
        simplex.push(v);
    }
    simplex
}

/// The best usable point of a trace and the spread of its `count` best usable points: the largest
/// extent over the parameters, as a fraction of each parameter's log-range (0 with fewer points).
fn best_points_spread(trace: &[Evaluation], count: usize, lo: &[Real], hi: &[Real]) -> (Option<Vec<Real>>, Real) {
    let mut usable: Vec<&Evaluation> = trace.iter().filter(|e| e.status.usable()).collect();
    usable.sort_by(|a, b| a.objective.total_cmp(&b.objective));
    usable.truncate(count);
    let spread = (0..lo.len())
        .map(|i| {
            let (min, max) =
                usable.iter().fold((Real::INFINITY, Real::NEG_INFINITY), |(a, b), e| (a.min(e.x[i]), b.max(e.x[i])));
            if usable.len() < 2 || hi[i] <= lo[i] { 0.0 } else { (max - min) / (hi[i] - lo[i]) }
        })
        .fold(0.0, Real::max);
    (usable.first().map(|e| e.x.clone()), spread)
}

/// Runs the configured optimiser until convergence or the budget; the best point is the trace's.
pub fn optimise(evaluator: &Evaluator<'_>, config: &OptimizerConfig) -> Result<OptimiserOutcome, InferenceError> {
    let space = &evaluator.model().space;
    let (lo, hi) = space.log_bounds();
    let max_iters = (config.max_evaluations as u64).saturating_mul(4) + 16;
    let result = match config.method {
        OptimizerMethod::NelderMead => {
            let mut center = space.initial_point();
            let mut fraction = config.initial_simplex;
            loop {
                let simplex = initial_simplex(&center, fraction, &lo, &hi);
                // The initial simplex is independent: evaluate it in parallel, the solver then hits the cache.
                match evaluator.evaluate_batch(&simplex, true) {
                    Err(Halt::Stopped) => return Err(InferenceError::Stopped),
                    Err(spent) => return Ok(OptimiserOutcome { converged: false, reason: spent.to_string() }),
                    Ok(_) => {}
                }
                let solver = NelderMead::new(simplex)
                    .with_sd_tolerance(config.tolerance)
                    .map_err(|e| InferenceError::Optimiser(e.to_string()))?;
                let run =
                    Executor::new(Problem(evaluator), solver).configure(|s| s.max_iters(max_iters)).run().map(|r| {
                        let state = r.state();
                        (state.get_termination_reason().map(|t| t.to_string()), state.get_termination_status().clone())
                    });
                // Converged by the spread of the objectives, the simplex may still be wide: two
                // vertices on either side of the minimum with equal objectives (measured: a 1-D fit
                // stopped after its two first points, ln-spaced 0.45 apart, 3.625 and 3.620, while
                // the minimum between them scored 0.41). Then it starts again around the best point
                // with half that width, until the best points lie within `simplex_tolerance`.
                if let Ok((
                    _,
                    argmin::core::TerminationStatus::Terminated(argmin::core::TerminationReason::SolverConverged),
                )) = &run
                {
                    let (best, spread) = best_points_spread(&evaluator.trace(), center.len() + 1, &lo, &hi);
                    // The width at least halves at every restart, so the restarts end.
                    let next = 0.5 * spread.min(fraction);
                    if spread > config.simplex_tolerance
                        && next >= 0.5 * config.simplex_tolerance
                        && let Some(best) = best
                    {
                        tracing::info!(
                            "Nelder–Mead converged on a simplex {spread:.3} of the log-range wide; restarting around the best point"
                        );
                        center = best;
                        fraction = next;
                        continue;
                    }
                }
                break run;
            }
        }
        OptimizerMethod::ParticleSwarm => {
            let rng = Xoshiro256PlusPlus::seed_from_u64(config.seed);
            let solver = ParticleSwarm::new((lo, hi), config.swarm_size).with_rng_generator(rng);
            let iters = (config.max_evaluations / config.swarm_size) as u64 + 1;
            Executor::new(Problem(evaluator), solver)
                .configure(|s| s.max_iters(iters).target_cost(config.tolerance))
                .run()
                .map(|r| {
                    let state = r.state();
                    (state.get_termination_reason().map(|t| t.to_string()), state.get_termination_status().clone())
                })
        }
    };
    match result {
        Ok((reason, status)) => {
            use argmin::core::{TerminationReason, TerminationStatus};
            let converged = matches!(
                status,
                TerminationStatus::Terminated(TerminationReason::SolverConverged)
                    | TerminationStatus::Terminated(TerminationReason::TargetCostReached)
            );
            Ok(OptimiserOutcome { converged, reason: reason.unwrap_or_else(|| "stopped".into()) })
        }
        Err(e) => {
            if let Some(Halt::Stopped) = e.downcast_ref::<Halt>() {
                Err(InferenceError::Stopped)
            } else if let Some(spent) = e.downcast_ref::<Halt>() {
                Ok(OptimiserOutcome { converged: false, reason: spent.to_string() })
            } else {
                Err(InferenceError::Optimiser(e.to_string()))
            }
        }
    }
}

/// The fit's wall time recorded by earlier sessions: the latest `elapsed_seconds` of a resumed
/// trace (0 for a fresh fit, and for a trace written before the column existed).
fn elapsed_before(preloaded: &[Evaluation]) -> Real {
    preloaded.iter().map(|e| e.elapsed_seconds).filter(|s| s.is_finite()).fold(0.0, Real::max)
}
