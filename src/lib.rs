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
