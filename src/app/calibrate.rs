//! The camera calibrated from photos of a printed QR code: `POST /v1/calibrate` and
//! `qrpose calibrate` (docs/calibration.md, Calibrating from photos).
//!
//! Each photo is decoded (within the image limits of a photo request), checked against the
//! first photo's size, and searched for codes (qrpose-detect, `balanced` effort, within the
//! server's detection deadline). Of the codes decoded, the one with the most calibration
//! points ([`calibration_points`]: finder corners, alignment centres and module corners,
//! each with its place on the printed code of the size given) is the photo's view; a photo
//! whose best code has fewer than [`MIN_POINTS_PER_VIEW`] points gives none. The views go to
//! [`qrpose_calib::calibrate`] (Zhang's closed form, one robust Levenberg-Marquardt, views
//! that do not fit dropped, standard deviations and warnings), and the camera found to the
//! calibration file writers of qrpose-site, so that the answer carries the files a site
//! file reads as they are.
//!
//! One view per photo: every code of a photo would be a plane of its own pose, but a
//! second code in a photo is as likely another label of another size as a second print of
//! the target.

use qrpose_calib::{
    CalibrationError, CameraCalibration, Correspondence, ImageSize, MIN_POINTS_PER_VIEW, MIN_VIEWS,
    Options, View,
};
use qrpose_core::geometry::camera::DistortionModel;
use qrpose_core::geometry::marker::Marker;
use qrpose_detect::decode::{self, DecodeError, DecodeLimits, GrayImage};
use qrpose_detect::refine::{TargetPoint, calibration_points};
use qrpose_detect::{Budget, CancelFlag, DetectorChoice, Effort, detect_within};
use std::time::{Duration, Instant};

/// Fewest photos a calibration takes: as many as the views it needs ([`MIN_VIEWS`]).
pub const MIN_PHOTOS: usize = MIN_VIEWS;

/// Most photos one calibration takes: 100 photos already hold some 40 000 points, and
/// each costs a detection on the worker that runs the request.
pub const MAX_PHOTOS: usize = 100;

/// A validated calibration request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrateSetup {
    /// The printed code: its side, quiet zone excluded.
    pub marker: Marker,
    /// The lens model to fit.
    pub model: DistortionModel,
    /// What each photo may cost to decode.
    pub decode: DecodeLimits,
    /// The detection deadline of each photo.
    pub max_detect: Duration,
}

/// What one photo gave.
#[derive(Debug, Clone, PartialEq)]
pub struct PhotoReport {
    /// Its index among the photos given, 0-based.
    pub index: usize,
    /// How many codes were decoded in it.
    pub codes_decoded: usize,
    /// The payload of the code used, when there is one.
    pub payload: Option<String>,
    /// The calibration points of the code used (none when no code was decoded).
    pub points: Vec<TargetPoint>,
    /// Its view among the calibration's ([`CameraCalibration::views`]); `None` when it gave
    /// none (no code, or fewer than [`MIN_POINTS_PER_VIEW`] points).
    pub view: Option<usize>,
}

/// A calibration and the photos it came from.
#[derive(Debug, Clone)]
pub struct CalibrateAnswer {
    /// Every photo, in the order given.
    pub photos: Vec<PhotoReport>,
    /// The camera, its standard deviations, every view's fit, the warnings.
    pub calibration: CameraCalibration,
    /// Decoding and detecting every photo and measuring its points, ms.
    pub detect_ms: f64,
    /// The solve, ms.
    pub solve_ms: f64,
}

/// Why the photos gave no calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrateError {
    /// Fewer than [`MIN_PHOTOS`] photos.
    #[error("{given} photos given; a calibration needs at least {required}, tilted differently")]
    TooFewPhotos {
        /// Photos given.
        given: usize,
        /// Photos needed.
        required: usize,
    },
    /// More than [`MAX_PHOTOS`] photos.
    #[error("{given} photos given; at most {max} are taken")]
    TooManyPhotos {
        /// Photos given.
        given: usize,
        /// The limit.
        max: usize,
    },
    /// A photo could not be read, or the request gave up while they were read.
    #[error(transparent)]
    Photo(#[from] PhotoError),
    /// No photo has a decoded code.
    #[error("no QR code was decoded in any of the {photos} photos")]
    NoCodeFound {
        /// Photos given.
        photos: usize,
    },
    /// Fewer than [`MIN_VIEWS`] photos have a code with enough points.
    #[error(
        "{usable} of {photos} photos show a code with at least {min_points} calibration points; a calibration needs at least {required} (photos without a code: {without_code})"
    )]
    TooFewViews {
        /// Photos given.
        photos: usize,
        /// Photos with a usable view.
        usable: usize,
        /// Views needed.
        required: usize,
        /// Points a view needs.
        min_points: usize,
        /// The photos without a decoded code, 0-based.
        without_code: String,
    },
    /// The solve refused the views (too few left once the poor ones were dropped, or the
    /// numbers failed).
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
}

/// Why photos could not be read, for a camera or a hand-eye calibration alike.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PhotoError {
    /// A photo is not an image this service reads, or is over the limits.
    #[error("photo {index}: {source}")]
    Decode {
        /// The photo, 0-based.
        index: usize,
        /// Why.
        source: DecodeError,
    },
    /// A photo's size differs from the first's.
    #[error(
        "photo {index} is {width_px} x {height_px} px, photo 0 {first_width_px} x {first_height_px} px: every photo must come from one camera at one resolution"
    )]
    MixedSizes {
        /// The photo, 0-based.
        index: usize,
        /// Its width, px.
        width_px: u32,
        /// Its height, px.
        height_px: u32,
        /// The first photo's width, px.
        first_width_px: u32,
        /// The first photo's height, px.
        first_height_px: u32,
    },
    /// The request gave up (a timeout, a closed connection) while the photos were read.
    #[error("the calibration was cancelled")]
    Cancelled,
}

/// Calibrates the camera from `photos` (JPEG, PNG or WebP bytes) as `setup` says; `cancel`
/// stops it between photos and ends the running detection early.
///
/// # Errors
/// [`CalibrateError`]: the photo count, a photo that does not decode or differs in size,
/// no code anywhere, too few views, the solve's refusal, cancellation.
pub fn calibrate_photos<B: AsRef<[u8]>>(
    setup: &CalibrateSetup,
    photos: &[B],
    cancel: &CancelFlag,
) -> Result<CalibrateAnswer, CalibrateError> {
    let given = photos.len();
    if given < MIN_PHOTOS {
        return Err(CalibrateError::TooFewPhotos {
            given,
            required: MIN_PHOTOS,
        });
    }
    if given > MAX_PHOTOS {
        return Err(CalibrateError::TooManyPhotos {
            given,
            max: MAX_PHOTOS,
        });
    }
    let read = read_photos(photos, &setup.decode, setup.max_detect, cancel, |_| {
        Some(setup.marker)
    })?;
    let mut reports = read.reports;
    let mut views = Vec::new();
    for report in &mut reports {
        if report.points.len() >= MIN_POINTS_PER_VIEW {
            report.view = Some(views.len());
            views.push(view_of(&report.points));
        }
    }
    let with_code = reports.iter().filter(|r| r.codes_decoded > 0).count();
    if with_code == 0 {
        return Err(CalibrateError::NoCodeFound { photos: given });
    }
    if views.len() < MIN_VIEWS {
        let without: Vec<String> = reports
            .iter()
            .filter(|r| r.codes_decoded == 0)
            .map(|r| r.index.to_string())
            .collect();
        return Err(CalibrateError::TooFewViews {
            photos: given,
            usable: views.len(),
            required: MIN_VIEWS,
            min_points: MIN_POINTS_PER_VIEW,
            without_code: if without.is_empty() {
                "none".to_owned()
            } else {
                without.join(", ")
            },
        });
    }
    let started = Instant::now();
    let options = Options {
        model: setup.model,
        ..Options::default()
    };
    let calibration = qrpose_calib::calibrate(&views, read.size, &options)?;
    Ok(CalibrateAnswer {
        photos: reports,
        calibration,
        detect_ms: read.detect_ms,
        solve_ms: ms_since(started),
    })
}

/// Photos read for a calibration: each one's report, their one size, and the time it took.
pub(super) struct ReadPhotos {
    /// Each photo's codes and points, in order.
    pub reports: Vec<PhotoReport>,
    /// The size every photo has (that of the first; 0 × 0 for no photo).
    pub size: ImageSize,
    /// Decoding and detecting every photo and measuring its points, ms.
    pub detect_ms: f64,
}

/// Decodes every photo, checks it against the first's size and measures its best code
/// ([`photo_points`], sized by `size_of`), in order; `cancel` stops it between photos.
///
/// # Errors
/// [`PhotoError`]: a photo that does not decode or differs in size, cancellation.
pub(super) fn read_photos<B: AsRef<[u8]>>(
    photos: &[B],
    limits: &DecodeLimits,
    max_detect: Duration,
    cancel: &CancelFlag,
    size_of: impl Fn(Option<&str>) -> Option<Marker>,
) -> Result<ReadPhotos, PhotoError> {
    let started = Instant::now();
    let mut size: Option<ImageSize> = None;
    let mut reports = Vec::with_capacity(photos.len());
    for (index, bytes) in photos.iter().enumerate() {
        if cancel.is_cancelled() {
            return Err(PhotoError::Cancelled);
        }
        let image = decode::decode_gray(bytes.as_ref(), limits)
            .map_err(|source| PhotoError::Decode { index, source })?;
        let this = image_size(&image);
        let first = *size.get_or_insert(this);
        if this != first {
            return Err(PhotoError::MixedSizes {
                index,
                width_px: this.width_px,
                height_px: this.height_px,
                first_width_px: first.width_px,
                first_height_px: first.height_px,
            });
        }
        reports.push(photo_points(&image, index, max_detect, cancel, &size_of));
    }
    Ok(ReadPhotos {
        reports,
        size: size.unwrap_or(ImageSize::new(0, 0)),
        detect_ms: ms_since(started),
    })
}

/// The decoded image's size.
fn image_size(image: &GrayImage) -> ImageSize {
    // Decoded sides are at most the decoder's limits, far below u32::MAX.
    let side = |x: usize| u32::try_from(x).unwrap_or(u32::MAX);
    ImageSize::new(side(image.width()), side(image.height()))
}

/// The codes of one photo, and the points of the decoded one with the most, each code
/// measured at the size `size_of` gives its payload (a code it gives none is left out).
fn photo_points(
    image: &GrayImage,
    index: usize,
    max_detect: Duration,
    cancel: &CancelFlag,
    size_of: impl Fn(Option<&str>) -> Option<Marker>,
) -> PhotoReport {
    let budget = Budget::new(Effort::Balanced, Some(max_detect)).cancelled_by(cancel.clone());
    // Auto needs no backend beyond the default build.
    let codes = detect_within(image, DetectorChoice::Auto, &budget)
        .map(|d| d.codes)
        .unwrap_or_default();
    let decoded: Vec<_> = codes
        .iter()
        .filter(|c| c.candidate.payload.is_some())
        .collect();
    let best = decoded
        .iter()
        .filter_map(|code| {
            let marker = size_of(code.candidate.text.as_deref())?;
            Some((code, calibration_points(image, code, &marker)))
        })
        .max_by_key(|(_, points)| points.len());
    let (payload, points) = match best {
        Some((code, points)) => (code.candidate.text.clone(), points),
        None => (None, Vec::new()),
    };
    PhotoReport {
        index,
        codes_decoded: decoded.len(),
        payload,
        points,
        view: None,
    }
}

/// The calibration view of a code's points: each point's (x, y) on the marker, mm, and
/// where the photo shows it.
pub(super) fn view_of(points: &[TargetPoint]) -> View {
    View {
        points: points
            .iter()
            .map(|p| {
                Correspondence::new(p.marker.0.x, p.marker.0.y, p.pixel_px.u(), p.pixel_px.v())
            })
            .collect(),
    }
}

pub(super) fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> CalibrateSetup {
        CalibrateSetup {
            marker: Marker::try_new(100.0).expect("a size"),
            model: DistortionModel::PlumbBob,
            decode: DecodeLimits::default(),
            max_detect: Duration::from_secs(5),
        }
    }

    #[test]
    fn the_photo_count_is_checked_before_any_photo_is_read() {
        let cancel = CancelFlag::new();
        let two = vec![b"not read".to_vec(); 2];
        assert!(matches!(
            calibrate_photos(&setup(), &two, &cancel),
            Err(CalibrateError::TooFewPhotos {
                given: 2,
                required: 3
            })
        ));
        let many = vec![b"not read".to_vec(); MAX_PHOTOS + 1];
        assert!(matches!(
            calibrate_photos(&setup(), &many, &cancel),
            Err(CalibrateError::TooManyPhotos { given: 101, .. })
        ));
        let garbage = vec![b"not an image".to_vec(); 3];
        assert!(matches!(
            calibrate_photos(&setup(), &garbage, &cancel),
            Err(CalibrateError::Photo(PhotoError::Decode { index: 0, .. }))
        ));
    }
}
