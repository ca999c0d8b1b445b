//! `qrpose-sim render --pick-scene SCENE.json --out DIR` and `--pick-study SEED [--picks N]
//! --out DIR`: photos of products on a robot's table from a camera on its flange, with the
//! truth of every product in view (docs/rendering.md, Picking scenes; library:
//! [`crate::pick`]). DIR gets `LABEL.jpg` per photo (JPEG at --jpeg-quality; `.png` with
//! --pick-png), `truth.json` (the scene, the effects, and per photo its flange pose and every
//! product in view), and for a study `scene.json` (loadable with --pick-scene) and
//! `site.yaml` (the matching site file). The effect flags apply; a summary goes to stdout.

use super::RenderArgs;
use crate::cli::Failure;
use crate::cli::problem::{Problem, parse_json};
use crate::pick::study::{study_scene, study_site_yaml};
use crate::pick::{PickScene, render_pick_scene};
use crate::render::{Effects, Encoding};
use clap::Args;
use serde_json::{Value, json};
use std::path::Path;

/// Default number of picks of a study.
pub const DEFAULT_PICKS: usize = 200;

/// The flags `--pick-scene` and `--pick-study` cannot be mixed with.
const PICK_CONFLICTS: [&str; 17] = [
    "scene",
    "random_scene",
    "payload",
    "ec_level",
    "marker_size_mm",
    "width_px",
    "height_px",
    "fx_px",
    "fy_px",
    "cx_px",
    "cy_px",
    "x_mm",
    "y_mm",
    "z_mm",
    "alpha_deg",
    "beta_deg",
    "gamma_deg",
];

/// The flags of the picking scenes.
#[derive(Debug, Args)]
pub struct PickArgs {
    /// Render a picking scene (JSON, docs/rendering.md): a camera on the flange, products,
    /// flange poses; --out is a directory.
    #[arg(long, value_name = "FILE.json", conflicts_with_all = PICK_CONFLICTS, conflicts_with = "sequence")]
    pub pick_scene: Option<std::path::PathBuf>,
    /// Generate and render a picking study drawn from this seed: --picks picks of three
    /// products, then a 20-frame approach; --out is a directory.
    #[arg(long, value_name = "SEED", conflicts_with_all = PICK_CONFLICTS, conflicts_with_all = ["sequence", "pick_scene"])]
    pub pick_study: Option<u64>,
    /// With --pick-study: the number of picks.
    #[arg(long, value_name = "N", requires = "pick_study", default_value_t = DEFAULT_PICKS)]
    pub picks: usize,
    /// Write PNG photos instead of JPEG.
    #[arg(long)]
    pub pick_png: bool,
}

impl PickArgs {
    /// Whether a picking scene was asked for.
    pub fn requested(&self) -> bool {
        self.pick_scene.is_some() || self.pick_study.is_some()
    }
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), Failure> {
    std::fs::write(path, bytes)
        .map_err(|e| Failure::Other(format!("cannot write {}: {e}", path.display())))
}

fn to_json_bytes(value: &impl serde::Serialize) -> Result<Vec<u8>, Failure> {
    serde_json::to_vec_pretty(value).map_err(|e| Failure::Other(e.to_string()))
}

/// Runs a picking render: the summary to print.
pub(super) fn run(args: &RenderArgs, effects: &Effects) -> Result<Value, Failure> {
    let pick = &args.pick;
    let out = &args.out;
    std::fs::create_dir_all(out)
        .map_err(|e| Failure::Other(format!("cannot create {}: {e}", out.display())))?;
    let scene: PickScene = match (&pick.pick_scene, pick.pick_study) {
        (Some(path), _) => {
            let text = std::fs::read(path)
                .map_err(|e| Failure::Other(format!("cannot read {}: {e}", path.display())))?;
            parse_json(&text)?
        }
        (None, Some(seed)) => {
            let scene = study_scene(seed, pick.picks)
                .map_err(|e| Problem::new("invalid_type", e.to_string()))?;
            write(&out.join("scene.json"), &to_json_bytes(&scene)?)?;
            write(&out.join("site.yaml"), study_site_yaml(&scene).as_bytes())?;
            scene
        }
        (None, None) => return Err(Failure::Other("no picking scene asked for".to_owned())),
    };
    let effects = Effects {
        encoding: if pick.pick_png {
            Encoding::Png
        } else {
            match effects.encoding {
                Encoding::Png => Encoding::Jpeg(super::DEFAULT_JPEG_QUALITY),
                jpeg => jpeg,
            }
        },
        ..*effects
    };
    let extension = if pick.pick_png { "png" } else { "jpg" };
    let rendered = render_pick_scene(&scene, &effects)
        .map_err(|e| Problem::new("invalid_type", e.to_string()))?;
    let mut photos = Vec::with_capacity(rendered.len());
    let mut in_view = 0;
    for r in &rendered {
        let file = format!("{}.{extension}", r.truth.label);
        write(&out.join(&file), &r.encoded)?;
        in_view += r.truth.products.len();
        let mut truth =
            serde_json::to_value(&r.truth).map_err(|e| Failure::Other(e.to_string()))?;
        if let Some(map) = truth.as_object_mut() {
            map.insert("image".to_owned(), json!(file));
        }
        photos.push(truth);
    }
    let truth = json!({"scene": scene, "effects": effects, "photos": photos});
    let truth_path = out.join("truth.json");
    write(&truth_path, &to_json_bytes(&truth)?)?;
    Ok(json!({
        "out": out,
        "photos": rendered.len(),
        "products_in_view": in_view,
        "truth": truth_path,
        "effects": effects,
    }))
}
