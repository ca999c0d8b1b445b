//! Heatmaps like the paper's Figures 8-12: the maximum solved angle at each P2 position.
//!
//! As in the paper, the horizontal axis is P2's y translation and the vertical axis its x
//! translation, both in mm; colour runs from 0° (dark) to 25° (yellow) on the viridis scale;
//! positions where even 0° is not solved ("diverged") are drawn white with a grey cross. One
//! SVG per set and distance, and one overview sheet per distance with the twelve sets in the
//! paper's panel order (a)-(l).

use super::grid::ANGLE_COUNT;
use super::run::{GridResult, Panel};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use thiserror::Error;

/// The colour scale's top, degrees (the grid's largest angle).
pub const SCALE_MAX_DEG: f64 = (ANGLE_COUNT - 1) as f64;

/// The paper's panel order in Figures 8-12: (a) X-0-0, (b) 0-Y-0, (c) 0-0-Z, (d) X-0-5, ….
pub const FIGURE_ORDER: [&str; 12] = [
    "X-0-0", "0-Y-0", "0-0-Z", "X-0-5", "0-Y-5", "0-5-Z", "X-5-0", "5-Y-0", "5-0-Z", "X-5-5",
    "5-Y-5", "5-5-Z",
];

const PANEL_LETTERS: [char; 12] = ['a', 'b', 'c', 'd', 'e', 'f', 'g', 'h', 'i', 'j', 'k', 'l'];

/// Why a heatmap could not be written.
#[derive(Debug, Error)]
pub enum HeatmapError {
    /// The drawing backend failed (e.g. the file could not be written).
    #[error("cannot draw {path}: {message}")]
    Draw {
        /// The file being written.
        path: String,
        /// What the backend said.
        message: String,
    },
}

fn colour(max_angle_deg: i32) -> Option<RGBColor> {
    (max_angle_deg >= 0)
        .then(|| ViridisRGB::get_color_normalized(f64::from(max_angle_deg), 0.0, SCALE_MAX_DEG))
}

type DrawResult = Result<(), Box<dyn std::error::Error>>;

fn draw_panel(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    panel: &Panel,
    caption: &str,
    font: u32,
) -> DrawResult {
    let half = 0.5 * panel.y_mm.windows(2).next().map_or(10.0, |w| w[1] - w[0]);
    let lo = panel
        .x_mm
        .iter()
        .chain(&panel.y_mm)
        .copied()
        .fold(f64::INFINITY, f64::min)
        - half;
    let hi = panel
        .x_mm
        .iter()
        .chain(&panel.y_mm)
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        + half;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", font))
        .margin(8)
        .x_label_area_size(font * 2)
        .y_label_area_size(font * 3)
        .build_cartesian_2d(lo..hi, lo..hi)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("y (mm)")
        .y_desc("x (mm)")
        .label_style(("sans-serif", font * 3 / 4))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .draw()?;
    // Cells overlap by a hair so that anti-aliasing leaves no white seams between them.
    let seam = 0.02 * half;
    let angles = panel.max_angles_deg();
    let mut k = 0;
    for &x in &panel.x_mm {
        for &y in &panel.y_mm {
            let cell = [
                (y - half - seam, x - half - seam),
                (y + half + seam, x + half + seam),
            ];
            match colour(angles[k]) {
                Some(c) => {
                    chart.draw_series(std::iter::once(Rectangle::new(cell, c.filled())))?;
                }
                None => {
                    chart.draw_series(std::iter::once(Rectangle::new(cell, WHITE.filled())))?;
                    let style = ShapeStyle::from(&RGBColor(150, 150, 150)).stroke_width(1);
                    let d = 0.6 * half;
                    chart.draw_series([
                        PathElement::new(vec![(y - d, x - d), (y + d, x + d)], style),
                        PathElement::new(vec![(y - d, x + d), (y + d, x - d)], style),
                    ])?;
                }
            }
            k += 1;
        }
    }
    Ok(())
}

fn draw_colour_bar(area: &DrawingArea<SVGBackend<'_>, Shift>, font: u32) -> DrawResult {
    let mut chart = ChartBuilder::on(area)
        .caption("max angle (°)", ("sans-serif", font * 3 / 4))
        .margin(8)
        .margin_top(40)
        .margin_bottom(60)
        .y_label_area_size(font * 2)
        .build_cartesian_2d(0.0..1.0, 0.0..SCALE_MAX_DEG)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_label_formatter(&|v| format!("{v:.0}"))
        .label_style(("sans-serif", font * 3 / 4))
        .draw()?;
    let steps = 100;
    chart.draw_series((0..steps).map(|i| {
        let a0 = SCALE_MAX_DEG * f64::from(i) / f64::from(steps);
        let a1 = SCALE_MAX_DEG * (f64::from(i) + 1.05) / f64::from(steps);
        let c = ViridisRGB::get_color_normalized(a0, 0.0, SCALE_MAX_DEG);
        Rectangle::new([(0.0, a0), (1.0, a1)], c.filled())
    }))?;
    area.draw(&Text::new(
        "× diverged",
        (4, area.dim_in_pixel().1 as i32 - 30),
        ("sans-serif", font * 3 / 4),
    ))?;
    Ok(())
}

fn draw_error(path: &Path, e: impl std::fmt::Display) -> HeatmapError {
    HeatmapError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// One panel with its colour bar.
///
/// # Errors
/// [`HeatmapError::Draw`] when the SVG cannot be drawn or written.
pub fn write_panel(panel: &Panel, method: &str, path: &Path) -> Result<(), HeatmapError> {
    let draw = || -> DrawResult {
        let root = SVGBackend::new(path, (620, 520)).into_drawing_area();
        root.fill(&WHITE)?;
        let (main, legend) = root.split_horizontally(520);
        let caption = format!("{} at {} mm ({method})", panel.set.name, panel.distance_mm);
        draw_panel(&main, panel, &caption, 18)?;
        draw_colour_bar(&legend, 18)?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| draw_error(path, e))
}

/// The twelve sets at one distance on one sheet, in the paper's (a)-(l) order.
///
/// # Errors
/// [`HeatmapError::Draw`] when the SVG cannot be drawn or written.
pub fn write_overview(
    result: &GridResult,
    distance_mm: f64,
    path: &Path,
) -> Result<(), HeatmapError> {
    let draw = || -> DrawResult {
        let root = SVGBackend::new(path, (1260, 1560)).into_drawing_area();
        root.fill(&WHITE)?;
        let title = format!(
            "Maximum solved angle, P2 at z = {distance_mm} mm ({})",
            result.method.as_str()
        );
        let root = root.titled(&title, ("sans-serif", 28))?;
        let (grid, legend) = root.split_horizontally(1140);
        let cells = grid.split_evenly((4, 3));
        for (i, name) in FIGURE_ORDER.iter().enumerate() {
            if let Some(panel) = result.panel(name, distance_mm) {
                let caption = format!(
                    "({}) {name}: {:.2} %",
                    PANEL_LETTERS[i],
                    panel.convergence_pct()
                );
                draw_panel(&cells[i], panel, &caption, 15)?;
            }
        }
        draw_colour_bar(&legend, 16)?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| draw_error(path, e))
}

/// Writes every panel and one overview per distance into `dir`; returns how many files.
///
/// # Errors
/// The first [`HeatmapError`].
pub fn write_all(result: &GridResult, dir: &Path) -> Result<usize, HeatmapError> {
    let method = result.method.as_str();
    let mut written = 0;
    for panel in &result.panels {
        let name = format!("{method}_{}_{}mm.svg", panel.set.name, panel.distance_mm);
        write_panel(panel, method, &dir.join(name))?;
        written += 1;
    }
    for &d in &result.spec.distances_mm {
        write_overview(result, d, &dir.join(format!("{method}_overview_{d}mm.svg")))?;
        written += 1;
    }
    Ok(written)
}
