//! The paper's Section 8 simulation, reproduced (docs/paper-method.md, The paper's simulation): the grid, the solved
//! criterion, Table 10, the heatmaps of Figures 8-12, Tables 5-9 and a noise study.

pub mod cli;
pub mod dataset;
pub mod evaluate;
pub mod grid;
pub mod heatmap;
pub mod pick;
pub mod report;
pub mod run;
pub mod tables;

pub mod render;

/// The README example, compiled and run as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
