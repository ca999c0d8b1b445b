//! Runs a method over the simulation grid and aggregates Table 10's figures.
//!
//! Work is split by (set, distance, x, y) position, each evaluating the 26 angles, in
//! parallel with rayon. Noise, when asked for, is drawn from a generator seeded by the case's
//! grid indices, so results do not depend on thread scheduling.

use super::evaluate::{Outcome, evaluate, refused};
use super::grid::{
    ANGLE_COUNT, Case, DISTANCES_MM, FOCAL_LENGTH_MM, MARKER_SIZE_MM, ROTATION_SETS, RotationSet,
    XY_COUNT, xy_mm,
};
use nalgebra::Vector3;
use qrpose_core::estimate::Method;
use qrpose_core::geometry::{
    camera::{Camera, CameraError},
    frames::PixelPoint,
    marker::{Marker, MarkerError},
};
use rand::{SeedableRng, rngs::StdRng};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;
use thiserror::Error;

/// Gaussian corner noise, as a real camera would add it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Standard deviation per coordinate, px.
    pub sigma_px: f64,
    /// Pixel pitch that turns px into image-plane mm, µm.
    pub pixel_size_um: f64,
    /// Seed of the noise; each case mixes in its grid indices.
    pub seed: u64,
}

/// Which part of the grid to run.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    /// Rotation sets, in output order.
    pub sets: Vec<RotationSet>,
    /// Working distances, mm, in output order.
    pub distances_mm: Vec<f64>,
    /// Take every `xy_stride`-th x and y position (1 = all 21 × 21).
    pub xy_stride: usize,
    /// Corner noise, or `None` for exact projection.
    pub noise: Option<Noise>,
}

impl GridSpec {
    /// The full grid of docs/paper-method.md, The paper's simulation, exact projection.
    pub fn full() -> Self {
        Self {
            sets: ROTATION_SETS.to_vec(),
            distances_mm: DISTANCES_MM.to_vec(),
            xy_stride: 1,
            noise: None,
        }
    }

    /// Indices of the x (and y) positions in use.
    pub fn xy_indices(&self) -> Vec<usize> {
        (0..XY_COUNT).step_by(self.xy_stride.max(1)).collect()
    }
}

/// One case's result, small enough to keep for the whole grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaseResult {
    /// Solved per docs/paper-method.md, The paper's simulation.
    pub solved: bool,
    /// Converged (the method's own criterion).
    pub converged: bool,
    /// max |ΔEuler|, degrees (∞ when the estimator refused the input).
    pub angle_error_deg: f64,
    /// max |Δz_i|, mm (∞ when refused).
    pub depth_error_mm: f64,
    /// Iterations of the judged estimate.
    pub iterations: u32,
}

impl From<&Outcome> for CaseResult {
    fn from(o: &Outcome) -> Self {
        Self {
            solved: o.solved,
            converged: o.estimate.as_ref().is_some_and(|e| e.diagnostics.converged),
            angle_error_deg: o.angle_error_deg,
            depth_error_mm: o.depth_error_mm,
            iterations: o.estimate.as_ref().map_or(0, |e| e.diagnostics.iterations),
        }
    }
}

/// The results of one (set, distance) panel: positions in row-major (x index, y index) order.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// The rotation set.
    pub set: RotationSet,
    /// The working distance, mm.
    pub distance_mm: f64,
    /// x positions, mm.
    pub x_mm: Vec<f64>,
    /// y positions, mm.
    pub y_mm: Vec<f64>,
    /// For each position, the 26 angles' results.
    pub cases: Vec<[CaseResult; ANGLE_COUNT]>,
}

impl Panel {
    /// The largest angle a such that every a' ≤ a is solved, or −1 ("diverged"), per position.
    pub fn max_angles_deg(&self) -> Vec<i32> {
        self.cases
            .iter()
            .map(|angles| {
                let solved = angles.iter().take_while(|c| c.solved).count();
                i32::try_from(solved).map_or(i32::MAX, |n| n - 1)
            })
            .collect()
    }

    /// Share of positions whose maximum angle is ≥ 0, % (Table 10).
    pub fn convergence_pct(&self) -> f64 {
        let ok = self.max_angles_deg().iter().filter(|a| **a >= 0).count();
        100.0 * ok as f64 / self.cases.len().max(1) as f64
    }

    /// Share of all position × angle cases solved, %.
    pub fn coverage_pct(&self) -> f64 {
        let solved: usize = self
            .cases
            .iter()
            .map(|a| a.iter().filter(|c| c.solved).count())
            .sum();
        100.0 * solved as f64 / (self.cases.len() * ANGLE_COUNT).max(1) as f64
    }
}

/// All panels of a run, in (set, distance) order.
#[derive(Debug, Clone, PartialEq)]
pub struct GridResult {
    /// The method run.
    pub method: Method,
    /// What was run.
    pub spec: GridSpec,
    /// One panel per set and distance, sets outer.
    pub panels: Vec<Panel>,
}

impl GridResult {
    /// The panel of a set and distance.
    pub fn panel(&self, set: &str, distance_mm: f64) -> Option<&Panel> {
        self.panels
            .iter()
            .find(|p| p.set.name == set && p.distance_mm == distance_mm)
    }

    /// Mean of the panels' convergence percentages (the paper's 77.28 % figure).
    pub fn overall_convergence_pct(&self) -> f64 {
        self.panels.iter().map(Panel::convergence_pct).sum::<f64>()
            / self.panels.len().max(1) as f64
    }

    /// Share of every case solved, %.
    pub fn overall_coverage_pct(&self) -> f64 {
        self.panels.iter().map(Panel::coverage_pct).sum::<f64>() / self.panels.len().max(1) as f64
    }

    /// Every case's result, for statistics.
    pub fn all_cases(&self) -> impl Iterator<Item = (&Panel, &CaseResult)> {
        self.panels.iter().flat_map(|p| {
            p.cases
                .iter()
                .flat_map(move |a| a.iter().map(move |c| (p, c)))
        })
    }
}

/// Why a simulation could not be set up.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum SimError {
    /// The simulated camera was refused.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The simulated marker was refused.
    #[error(transparent)]
    Marker(#[from] MarkerError),
}

/// The paper's camera (image-plane mm, f = 2.82 mm) and marker (50 mm).
///
/// # Errors
/// Only if the constants were changed to invalid values.
pub fn paper_setup() -> Result<(Camera, Marker), SimError> {
    Ok((
        Camera::image_plane_mm(FOCAL_LENGTH_MM)?,
        Marker::try_new(MARKER_SIZE_MM)?,
    ))
}

/// A seed for one case: the run's seed mixed with the case's grid indices (SplitMix64).
fn case_seed(seed: u64, indices: [usize; 5]) -> u64 {
    let mut z = seed;
    for i in indices {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15).wrapping_add(i as u64);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
    }
    z
}

/// Adds seeded Gaussian noise of σ px (× pixel pitch) to image-plane corners.
fn noisy(corners: [PixelPoint; 4], noise: &Noise, seed: u64) -> [PixelPoint; 4] {
    let sigma_mm = noise.sigma_px * noise.pixel_size_um * 1e-3;
    let Ok(normal) = Normal::new(0.0, sigma_mm) else {
        return corners;
    };
    let mut rng = StdRng::seed_from_u64(seed);
    corners.map(|p| {
        PixelPoint::new(
            p.u() + normal.sample(&mut rng),
            p.v() + normal.sample(&mut rng),
        )
    })
}

/// Runs `method` over `spec`; `progress` is called once per finished position.
///
/// # Errors
/// [`SimError`] if the paper's camera or marker cannot be built.
pub fn run_grid(
    method: Method,
    spec: &GridSpec,
    progress: &(dyn Fn() + Sync),
) -> Result<GridResult, SimError> {
    let (camera, marker) = paper_setup()?;
    let xy = spec.xy_indices();
    let mut panels = Vec::new();
    for (si, set) in spec.sets.iter().enumerate() {
        for (di, &z) in spec.distances_mm.iter().enumerate() {
            let positions: Vec<(usize, usize)> = xy
                .iter()
                .flat_map(|&i| xy.iter().map(move |&j| (i, j)))
                .collect();
            let cases: Vec<[CaseResult; ANGLE_COUNT]> = positions
                .par_iter()
                .map(|&(i, j)| {
                    let result = std::array::from_fn(|a| {
                        let case = Case {
                            p2_mm: Vector3::new(xy_mm(i), xy_mm(j), z),
                            set: *set,
                            angle_deg: a as f64,
                        };
                        let Some(exact) = case.image_plane_corners_mm(&marker, FOCAL_LENGTH_MM)
                        else {
                            return CaseResult::from(&refused());
                        };
                        let corners = match &spec.noise {
                            Some(n) => noisy(exact, n, case_seed(n.seed, [si, di, i, j, a])),
                            None => exact,
                        };
                        CaseResult::from(&evaluate(&case, &corners, &camera, &marker, method))
                    });
                    progress();
                    result
                })
                .collect();
            panels.push(Panel {
                set: *set,
                distance_mm: z,
                x_mm: xy.iter().map(|&i| xy_mm(i)).collect(),
                y_mm: xy.iter().map(|&j| xy_mm(j)).collect(),
                cases,
            });
        }
    }
    Ok(GridResult {
        method,
        spec: spec.clone(),
        panels,
    })
}
