//! tissuefit: from a segmented 3D image of a tissue to the mechanical parameters of its cells.
//!
//! Stages (see `DESIGN.md`): mesh the labelled cells into closed triangle surfaces, simulate the
//! SimuCell3D deformable-cell model to equilibrium, measure morphology, and fit surface tension and
//! adhesion so that simulated and observed morphology agree. Dependencies point one way:
//! `geometry ← files ← mesh ← {imaging, meshing, mechanics, morphology} ← io ← {inference, render} ← stages ←
//! pipeline ← cli` (`files`: atomic writes, capped reads and unit-slip checks, below everything that
//! knows about cells; morphology never depends on mechanics: it measures segmented tissues too).
//! `ARCHITECTURE.md` has the module map and the rule.

pub mod cli;
pub mod files;
pub mod fuzzing;
pub mod geometry;
pub mod imaging;
pub mod inference;
pub mod io;
pub mod mechanics;
pub mod mesh;
pub mod meshing;
pub mod morphology;
pub mod pipeline;
pub mod render;
pub mod stages;

/// Runs `f` on a worker thread of rayon's pool: the current pool's when called from inside one, the
/// global pool's otherwise (the calling thread blocks until `f` returns). Every parallel loop inside
/// `f` then starts by work stealing; called from a thread outside the pool (a Python call, a
/// program's main thread) each loop would instead wake the pool and wait for it (a futex round
/// trip), which made a 20-cell fit 1.4× slower on one thread (`tissuefit bench fit` against
/// `examples/fit_aggregate.rs` before it ran here). The CLI runs every command inside its pool.
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        return f();
    }
    // From outside a pool, rayon runs the whole `join` on one of the global pool's workers.
    rayon::join(f, || ()).0
}
