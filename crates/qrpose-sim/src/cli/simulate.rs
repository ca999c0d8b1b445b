//! `qrpose-sim simulate`: the paper's Section 8 experiment (docs/paper-method.md, The paper's simulation).

use crate::{
    grid::{DISTANCES_MM, ROTATION_SETS, rotation_set},
    report,
    run::{GridSpec, Noise, run_grid},
};
use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use qrpose_core::estimate::Method;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

/// Output format.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Format {
    /// Table 10 beside the paper's, as text.
    Table,
    /// JSON document of `docs/paper-method.md` (The `simulate` output).
    Json,
    /// One CSV row per set and distance.
    Csv,
}

/// Solver, as on the wire.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// The paper's iteration, with its gain sweep.
    Paper,
    /// The paper's equations by Levenberg-Marquardt.
    DepthNewton,
    /// IPPE + Levenberg-Marquardt on image error.
    Reprojection,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Paper => Method::Paper,
            MethodArg::DepthNewton => Method::DepthNewton,
            MethodArg::Reprojection => Method::Reprojection,
        }
    }
}

/// Arguments of `simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// The solver to evaluate.
    #[arg(long, value_enum, default_value = "paper")]
    pub method: MethodArg,
    /// Output format on stdout.
    #[arg(long, value_enum, default_value = "table")]
    pub format: Format,
    /// Write heatmaps (one SVG per set and distance, one overview per distance) and the
    /// per-position maximum angles (CSV) into this directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Only these rotation sets (comma-separated, e.g. X-0-0,5-5-Z).
    #[arg(long, value_delimiter = ',')]
    pub sets: Vec<String>,
    /// Only these working distances, mm (comma-separated, from 500,400,300,200,100).
    #[arg(long, value_delimiter = ',')]
    pub distances_mm: Vec<f64>,
    /// Use every N-th x and y position (1 = the full 21 × 21).
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// Add Gaussian noise of this many pixels (σ per coordinate) to the corners.
    #[arg(long)]
    pub noise_px: Option<f64>,
    /// Pixel pitch for `--noise-px`, µm.
    #[arg(long, default_value_t = 1.4)]
    pub pixel_size_um: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the paper's Tables 5-9 cases beside every method's estimate instead.
    #[arg(long)]
    pub tables: bool,
}

fn grid_spec(args: &SimulateArgs) -> anyhow::Result<GridSpec> {
    let sets = if args.sets.is_empty() {
        ROTATION_SETS.to_vec()
    } else {
        args.sets
            .iter()
            .map(|s| rotation_set(s).with_context(|| format!("unknown rotation set {s:?}")))
            .collect::<anyhow::Result<_>>()?
    };
    let distances_mm = if args.distances_mm.is_empty() {
        DISTANCES_MM.to_vec()
    } else {
        args.distances_mm.clone()
    };
    for d in &distances_mm {
        if !DISTANCES_MM.contains(d) {
            bail!("distance {d} mm is not on the grid (500, 400, 300, 200, 100)");
        }
    }
    if args.stride == 0 {
        bail!("--stride must be at least 1");
    }
    let noise = match args.noise_px {
        Some(sigma_px) if sigma_px.is_finite() && sigma_px > 0.0 && args.pixel_size_um > 0.0 => {
            Some(Noise {
                sigma_px,
                pixel_size_um: args.pixel_size_um,
                seed: args.seed,
            })
        }
        Some(_) => bail!("--noise-px and --pixel-size-um must be positive"),
        None => None,
    };
    Ok(GridSpec {
        sets,
        distances_mm,
        xy_stride: args.stride,
        noise,
    })
}

fn progress_bar(total: u64) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {pos}/{len} positions ({eta} left)",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

/// Runs `simulate`.
pub fn run(args: &SimulateArgs) -> anyhow::Result<ExitCode> {
    if args.tables {
        print!("{}", crate::tables::comparison_text()?);
        return Ok(ExitCode::SUCCESS);
    }
    let spec = grid_spec(args)?;
    let positions = spec.xy_indices().len().pow(2) * spec.sets.len() * spec.distances_mm.len();
    let bar = progress_bar(positions as u64);
    let started = std::time::Instant::now();
    let result = run_grid(args.method.into(), &spec, &|| bar.inc(1))?;
    bar.finish_and_clear();
    let elapsed = started.elapsed();
    match args.format {
        Format::Table => {
            print!("{}", report::to_table(&result));
            eprintln!(
                "{positions} positions × 26 angles in {:.1} s",
                elapsed.as_secs_f64()
            );
        }
        Format::Json => println!(
            "{}",
            serde_json::to_string_pretty(&report::to_json(&result))?
        ),
        Format::Csv => print!("{}", report::to_csv(&result)),
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        std::fs::write(dir.join("max_angles.csv"), report::max_angles_csv(&result))?;
        let written = crate::heatmap::write_all(&result, dir)?;
        eprintln!("wrote {} heatmaps to {}", written, dir.display());
    }
    Ok(ExitCode::SUCCESS)
}
