//! A request, validated: the [`Setup`] every operation takes, and the detection settings
//! of image requests ([`ImageSetup`]).
//!
//! A setup is built once per request by `api::` (from JSON, query parameters or flags) and
//! never checked again. It holds the site snapshot the request was validated against, so a
//! reload in the middle of a request cannot change what it sees.

use super::prior::Prior;
use qrpose_core::estimate::ValidSolver;
use qrpose_core::geometry::{camera::Camera, marker::Marker};
use qrpose_detect::decode::DecodeLimits;
use qrpose_detect::pipeline::{MarkerSizes, Options, Points};
use qrpose_detect::{Budget, DetectorChoice, Effort, cancel::CancelFlag};
use qrpose_site::pick::DEFAULT_MIN_GRASP_PROBABILITY;
use qrpose_site::transform::Rigid;
use qrpose_site::{Site, SiteCamera, SizeSource};
use std::sync::Arc;
use std::time::Duration;

/// How the codes of a request are sized.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sizing {
    /// One size for every code, and where it came from (the request, or for a corners
    /// request the site's rule for its payload).
    Fixed {
        /// The printed code.
        marker: Marker,
        /// Where its size came from.
        source: SizeSource,
    },
    /// Each code by its payload, from the site's rules.
    BySite,
}

/// What every operation takes: a validated request.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The camera of the image (or of the corners).
    pub camera: Camera,
    /// The site camera the request named (`camera.id`): its mount puts poses in the robot's
    /// frame.
    pub site_camera: Option<SiteCamera>,
    /// The site the request was validated against; `None` without `--site`.
    pub site: Option<Arc<Site>>,
    /// How each code is sized.
    pub sizing: Sizing,
    /// The solver, range-checked.
    pub solver: ValidSolver,
    /// An expected orientation that decides the planar ambiguity.
    pub prior: Option<Prior>,
    /// The arm's pose when the image was taken, and the bar a grasp must clear.
    pub pick: Pick,
}

/// What picking takes from a request (`docs/pick.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pick {
    /// T_robot←flange when the image was taken (`flange_pose`): with a camera on the
    /// flange, the robot frame exists only with it.
    pub flange: Option<Rigid>,
    /// The least probability of landing within tolerance for a grasp to be `graspable`.
    pub min_grasp_probability: f64,
}

impl Default for Pick {
    fn default() -> Self {
        Self {
            flange: None,
            min_grasp_probability: DEFAULT_MIN_GRASP_PROBABILITY,
        }
    }
}

impl Setup {
    /// The marker-size resolver of this setup, for the detector.
    #[must_use]
    pub fn sizes(&self) -> SizeResolver<'_> {
        SizeResolver::new(self.sizing, self.site.as_deref())
    }
}

/// The size of a code by its payload: the setup's one size, or the site's rules. The
/// detector asks it for each code before solving, so each code is solved once.
#[derive(Debug, Clone, Copy)]
pub struct SizeResolver<'a> {
    sizing: Sizing,
    site: Option<&'a Site>,
}

impl<'a> SizeResolver<'a> {
    /// The resolver of `sizing` against `site`'s rules.
    #[must_use]
    pub fn new(sizing: Sizing, site: Option<&'a Site>) -> Self {
        Self { sizing, site }
    }
}

impl MarkerSizes for SizeResolver<'_> {
    type Source = SizeSource;

    fn marker_for(&self, payload: Option<&str>) -> Option<(Marker, SizeSource)> {
        match self.sizing {
            Sizing::Fixed { marker, source } => Some((marker, source)),
            Sizing::BySite => {
                let lookup = self.site?.sizes().lookup(payload)?;
                // The site file's sizes are validated when it loads.
                let marker = Marker::try_new(lookup.size_mm).ok()?;
                Some((marker, lookup.source))
            }
        }
    }
}

/// What the server (or the command line) allows an image request: the decode limits and
/// the largest detection deadline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageLimits {
    /// Encoded size and declared pixel count.
    pub decode: DecodeLimits,
    /// The largest detection deadline a request may ask for; also the cap of an effort's
    /// default deadline.
    pub max_detect: Duration,
}

/// How an image request looks for codes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectSetup {
    /// Which detector backend(s).
    pub detector: DetectorChoice,
    /// Which points each pose is solved from.
    pub points: Points,
    /// How hard to look.
    pub effort: Effort,
    /// The deadline the request asked for, already capped by the server; `None` for the
    /// effort's default for the image, capped by `max_detect`.
    pub max_detect: Option<Duration>,
    /// The server's cap on the deadline ([`ImageLimits::max_detect`]).
    pub max_detect_cap: Duration,
}

impl DetectSetup {
    /// The detection budget for an image of `pixels` pixels, stopped by `cancel`: the
    /// deadline asked for, else the effort's default for the image within the cap.
    #[must_use]
    pub fn budget(&self, pixels: usize, cancel: CancelFlag) -> Budget {
        let deadline = self.max_detect.unwrap_or_else(|| {
            self.effort
                .default_deadline(pixels)
                .min(self.max_detect_cap)
        });
        Budget::new(self.effort, Some(deadline)).cancelled_by(cancel)
    }

    /// The detector's options for an image of `pixels` pixels.
    #[must_use]
    pub fn options(&self, pixels: usize, cancel: CancelFlag) -> Options {
        Options {
            detector: self.detector,
            points: self.points,
            budget: self.budget(pixels, cancel),
        }
    }
}

/// A validated image request.
#[derive(Debug, Clone)]
pub struct ImageSetup {
    /// Camera, sizes, solver, prior.
    pub pose: Setup,
    /// Detector, points, budget.
    pub detect: DetectSetup,
    /// What the image may cost to decode.
    pub decode: DecodeLimits,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn site() -> Arc<Site> {
        let text = "cameras:\n  front:\n    intrinsics: {fx_px: 900, fy_px: 900, cx_px: 320, cy_px: 240}\n\
                    markers:\n  sizes:\n    - {prefix: \"LOC-\", size_mm: 80}\n";
        Arc::new(Site::parse(text, Path::new("site.yaml")).expect("a valid site"))
    }

    #[test]
    fn a_resolver_sizes_by_the_request_then_by_the_site() {
        let site = site();
        let fixed = Marker::try_new(33.0).expect("a size");
        let by_request = SizeResolver {
            sizing: Sizing::Fixed {
                marker: fixed,
                source: SizeSource::Request,
            },
            site: Some(&site),
        };
        assert_eq!(
            by_request.marker_for(Some("LOC-1")),
            Some((fixed, SizeSource::Request))
        );
        let by_site = SizeResolver {
            sizing: Sizing::BySite,
            site: Some(&site),
        };
        let (marker, source) = by_site.marker_for(Some("LOC-1")).expect("sized");
        assert_eq!((marker.size_mm(), source), (80.0, SizeSource::SitePrefix));
        assert_eq!(
            by_site.marker_for(Some("SKU-1")),
            None,
            "no rule, no default"
        );
        assert_eq!(by_site.marker_for(None), None, "an undecoded code");
    }

    #[test]
    fn the_default_deadline_is_the_effort_s_own_within_the_cap() {
        let hd = 1920 * 1080;
        let setup = DetectSetup {
            detector: DetectorChoice::Auto,
            points: Points::Corners,
            effort: Effort::Balanced,
            max_detect: None,
            max_detect_cap: Duration::from_secs(5),
        };
        let own = Effort::Balanced.default_deadline(hd);
        assert_eq!(setup.budget(hd, CancelFlag::new()).max_detect, Some(own));
        let tight = DetectSetup {
            max_detect_cap: Duration::from_millis(3),
            ..setup
        };
        assert_eq!(
            tight.budget(hd, CancelFlag::new()).max_detect,
            Some(Duration::from_millis(3))
        );
        let asked = DetectSetup {
            max_detect: Some(Duration::from_millis(40)),
            ..setup
        };
        assert_eq!(
            asked.budget(hd, CancelFlag::new()).max_detect,
            Some(Duration::from_millis(40))
        );
    }
}
