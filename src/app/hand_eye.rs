//! The camera's pose on a robot from photos of a printed code and the flange pose of each:
//! `POST /v1/calibrate/hand-eye` and `qrpose calibrate hand-eye` (`docs/hand-eye.md`).
//!
//! Each photo is decoded, checked against the first photo's size and searched for codes as
//! a camera calibration's photos are (the same points: finder corners, alignment centres,
//! module corners); the code with the most points is the photo's view, measured at the size
//! the request gives or the site gives its payload. The views and the flange poses go to
//! [`calibrate_hand_eye`]: a closed form on the per-view poses, then one
//! robust fit of the mount, the target and every flange pose as a noisy measurement.

use super::calibrate::{PhotoError, PhotoReport, ms_since, read_photos, view_of};
use super::setup::{SizeResolver, Sizing};
use qrpose_calib::handeye::{
    FlangeNoise, HandEyeCalibration, HandEyeError, HandEyeOptions, HandEyeSetup, HandEyeView,
    MIN_HAND_EYE_VIEWS, calibrate_hand_eye,
};
use qrpose_core::geometry::camera::Camera;
use qrpose_detect::cancel::CancelFlag;
use qrpose_detect::decode::DecodeLimits;
use qrpose_detect::pipeline::MarkerSizes;
use qrpose_site::Site;
use qrpose_site::transform::Rigid;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Most photos one hand-eye calibration takes.
pub const MAX_HAND_EYE_PHOTOS: usize = 100;

/// A validated hand-eye request.
#[derive(Debug, Clone)]
pub struct HandEyeRequestSetup {
    /// Eye-in-hand or eye-to-hand.
    pub setup: HandEyeSetup,
    /// The camera that took the photos (pixel form, with its lens).
    pub camera: Camera,
    /// How the code is sized: the request's size, or the site's rule for its payload.
    pub sizing: Sizing,
    /// The site the request was validated against (its size rules); `None` without one.
    pub site: Option<Arc<Site>>,
    /// T_robot←flange when each photo was taken, in the photos' order.
    pub flange_poses: Vec<Rigid>,
    /// How noisy the controller's flange poses are.
    pub flange_noise: FlangeNoise,
    /// What each photo may cost to decode.
    pub decode: DecodeLimits,
    /// The detection deadline of each photo.
    pub max_detect: Duration,
}

/// A hand-eye calibration and the photos it came from.
#[derive(Debug, Clone)]
pub struct HandEyeAnswer {
    /// Every photo, in the order given.
    pub photos: Vec<PhotoReport>,
    /// The mount, the target, their uncertainty, the residuals, the warnings.
    pub calibration: HandEyeCalibration,
    /// Decoding and detecting every photo and measuring its points, ms.
    pub detect_ms: f64,
    /// The solve, ms.
    pub solve_ms: f64,
}

/// Why the photos gave no hand-eye calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HandEyeRequestError {
    /// Not one flange pose per photo.
    #[error("{photos} photos and {poses} flange poses: give one flange pose per photo, in order")]
    FlangePosesMismatch {
        /// Photos given.
        photos: usize,
        /// Flange poses given.
        poses: usize,
    },
    /// Fewer than [`MIN_HAND_EYE_VIEWS`] photos.
    #[error("{given} photos given; a hand-eye calibration needs at least {required}")]
    TooFewPhotos {
        /// Photos given.
        given: usize,
        /// Photos needed.
        required: usize,
    },
    /// More than [`MAX_HAND_EYE_PHOTOS`] photos.
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
    /// No photo has a decoded code of a known size.
    #[error("no QR code of a known size was decoded in any of the {photos} photos")]
    NoCodeFound {
        /// Photos given.
        photos: usize,
    },
    /// The solve refused the views.
    #[error(transparent)]
    Solve(#[from] HandEyeError),
}

/// Calibrates the camera's mount from `photos` (JPEG, PNG or WebP) and the flange poses of
/// `setup`; `cancel` stops it between photos.
///
/// # Errors
/// [`HandEyeRequestError`]: the counts, a photo that does not decode or differs in size,
/// no code anywhere, the solve's refusals (too few views read, degenerate motion).
pub fn calibrate_hand_eye_photos<B: AsRef<[u8]>>(
    setup: &HandEyeRequestSetup,
    photos: &[B],
    cancel: &CancelFlag,
) -> Result<HandEyeAnswer, HandEyeRequestError> {
    let given = photos.len();
    if setup.flange_poses.len() != given {
        return Err(HandEyeRequestError::FlangePosesMismatch {
            photos: given,
            poses: setup.flange_poses.len(),
        });
    }
    if given < MIN_HAND_EYE_VIEWS {
        return Err(HandEyeRequestError::TooFewPhotos {
            given,
            required: MIN_HAND_EYE_VIEWS,
        });
    }
    if given > MAX_HAND_EYE_PHOTOS {
        return Err(HandEyeRequestError::TooManyPhotos {
            given,
            max: MAX_HAND_EYE_PHOTOS,
        });
    }
    let sizes = SizeResolver::new(setup.sizing, setup.site.as_deref());
    let size_of = |payload: Option<&str>| sizes.marker_for(payload).map(|(marker, _)| marker);
    let read = read_photos(photos, &setup.decode, setup.max_detect, cancel, size_of)?;
    let Some(marker) = read
        .reports
        .iter()
        .find(|r| !r.points.is_empty())
        .and_then(|r| size_of(r.payload.as_deref()))
    else {
        return Err(HandEyeRequestError::NoCodeFound { photos: given });
    };
    let views: Vec<HandEyeView> = read
        .reports
        .iter()
        .zip(&setup.flange_poses)
        .map(|(report, flange)| HandEyeView {
            correspondences: view_of(&report.points).points,
            flange_pose: flange.to_isometry(),
        })
        .collect();
    let started = Instant::now();
    let calibration = calibrate_hand_eye(
        &setup.camera,
        read.size,
        &marker,
        &views,
        setup.setup,
        &HandEyeOptions {
            flange_noise: setup.flange_noise,
            ..HandEyeOptions::default()
        },
    )?;
    Ok(HandEyeAnswer {
        photos: read.reports,
        calibration,
        detect_ms: read.detect_ms,
        solve_ms: ms_since(started),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use qrpose_core::geometry::camera::Camera;
    use qrpose_core::geometry::marker::Marker;
    use qrpose_site::SizeSource;

    fn setup(poses: usize) -> HandEyeRequestSetup {
        HandEyeRequestSetup {
            setup: HandEyeSetup::EyeInHand,
            camera: Camera::from_pixels(1000.0, 1000.0, 639.5, 359.5).expect("a camera"),
            sizing: Sizing::Fixed {
                marker: Marker::try_new(120.0).expect("a size"),
                source: SizeSource::Request,
            },
            site: None,
            flange_poses: vec![Rigid::identity(); poses],
            flange_noise: FlangeNoise::default(),
            decode: DecodeLimits::default(),
            max_detect: Duration::from_secs(5),
        }
    }

    #[test]
    fn the_counts_are_checked_before_any_photo_is_read() {
        let cancel = CancelFlag::new();
        let five = vec![b"not read".to_vec(); 5];
        assert!(matches!(
            calibrate_hand_eye_photos(&setup(4), &five, &cancel),
            Err(HandEyeRequestError::FlangePosesMismatch {
                photos: 5,
                poses: 4
            })
        ));
        let three = vec![b"not read".to_vec(); 3];
        assert!(matches!(
            calibrate_hand_eye_photos(&setup(3), &three, &cancel),
            Err(HandEyeRequestError::TooFewPhotos { given: 3, .. })
        ));
        assert!(matches!(
            calibrate_hand_eye_photos(&setup(5), &five, &cancel),
            Err(HandEyeRequestError::Photo(PhotoError::Decode {
                index: 0,
                ..
            }))
        ));
    }

    /// A grey PNG of `side` × `side` px.
    fn png(side: u32) -> Vec<u8> {
        let mut bytes = std::io::Cursor::new(Vec::new());
        image::GrayImage::from_pixel(side, side, image::Luma([128]))
            .write_to(&mut bytes, image::ImageFormat::Png)
            .expect("a PNG");
        bytes.into_inner()
    }

    #[test]
    fn a_photo_of_another_size_is_named_with_both_sizes() {
        let photos = [png(32), png(32), png(32), png(48)];
        let err = calibrate_hand_eye_photos(&setup(4), &photos, &CancelFlag::new())
            .expect_err("mixed sizes");
        assert!(matches!(
            err,
            HandEyeRequestError::Photo(PhotoError::MixedSizes {
                index: 3,
                width_px: 48,
                first_width_px: 32,
                ..
            })
        ));
        assert!(
            err.to_string().contains("48 x 48 px, photo 0 32 x 32 px"),
            "{err}"
        );
    }
}
