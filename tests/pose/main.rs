//! The pose from four corners through the library: the paper's method against a plain
//! second implementation and its printed tables, the paper's simulation, property tests of
//! every solver, extreme inputs, the planar ambiguity and the covariance against Monte
//! Carlo spreads.

mod ambiguity;
mod covariance;
mod extreme_inputs;
mod paper_spec_reference;
mod paper_tables;
mod properties;
mod simulation;
