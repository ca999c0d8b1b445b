//! A request's camera and marker size resolved against the loaded site, if any
//! (`docs/site.md`, Requests): `camera.id` names a site camera instead of intrinsics, and a
//! marker size omitted from the request comes from the site's rules for the payload.

use super::problem::{ErrorCode, Problem};
use super::request::{CameraDto, CornersUnit, MarkerDto};
use crate::geometry::{camera::Camera, marker::Marker};
use qrpose_site::{Site, SiteCamera, SizeSource};

/// The JSON pointer of a camera id.
pub const CAMERA_ID_POINTER: &str = "/camera/id";
/// The JSON pointer of the marker.
pub const MARKER_POINTER: &str = "/marker";

/// The camera of a request.
#[derive(Debug, Clone, Copy)]
pub struct ResolvedCamera<'a> {
    /// The camera model.
    pub camera: Camera,
    /// Image-plane mm per pixel, for `corners_mm` with a pixel size.
    pub mm_per_px: Option<f64>,
    /// The site camera, when the request named one.
    pub site_camera: Option<&'a SiteCamera>,
}

/// The camera of `dto`: the site camera it names by `id`, or its own intrinsics.
///
/// # Errors
/// 422 `unknown_camera` for an id without a site or not in it; `incomplete_camera` for an
/// id with other camera fields, or with `corners_mm`; the intrinsics' own problems.
pub fn resolve_camera<'a>(
    dto: &CameraDto,
    unit: CornersUnit,
    site: Option<&'a Site>,
) -> Result<ResolvedCamera<'a>, Problem> {
    let Some(id) = &dto.id else {
        let (camera, mm_per_px) = dto.to_camera(unit)?;
        return Ok(ResolvedCamera {
            camera,
            mm_per_px,
            site_camera: None,
        });
    };
    let only_id = CameraDto {
        id: Some(id.clone()),
        ..CameraDto::default()
    };
    if *dto != only_id {
        return Err(Problem::new(
            ErrorCode::IncompleteCamera,
            "give camera.id alone (the site has its intrinsics and distortion), or the intrinsics without id",
        )
        .with_field("/camera"));
    }
    if unit == CornersUnit::Mm {
        return Err(Problem::new(
            ErrorCode::IncompleteCamera,
            "a site camera is a pixel camera: send corners_px, not corners_mm",
        )
        .with_field(CAMERA_ID_POINTER));
    }
    let site = site.ok_or_else(|| {
        Problem::new(
            ErrorCode::UnknownCamera,
            format!("camera {id:?}: no site is loaded (qrpose serve --site FILE)"),
        )
        .with_field(CAMERA_ID_POINTER)
    })?;
    let site_camera = site.camera(id).ok_or_else(|| {
        let known: Vec<&str> = site.cameras().keys().map(String::as_str).collect();
        Problem::new(
            ErrorCode::UnknownCamera,
            format!(
                "no camera {id:?} in the site {}; its cameras are: {}",
                site.file().display(),
                if known.is_empty() {
                    "none".to_owned()
                } else {
                    known.join(", ")
                }
            ),
        )
        .with_field(CAMERA_ID_POINTER)
    })?;
    Ok(ResolvedCamera {
        camera: site_camera.camera,
        mm_per_px: None,
        site_camera: Some(site_camera),
    })
}

/// The marker of a code with `payload`: the request's size, else the site's.
///
/// # Errors
/// `invalid_marker_size` for a bad request size; 422 `missing_field` (`/marker`) without a
/// request size and without a site; `unknown_marker_size` (field `payload_pointer`) when
/// the site has no size for the payload.
pub fn resolve_marker(
    request: Option<&MarkerDto>,
    site: Option<&Site>,
    payload: Option<&str>,
    payload_pointer: &str,
) -> Result<(Marker, SizeSource), Problem> {
    if let Some(m) = request {
        return Ok((m.to_marker()?, SizeSource::Request));
    }
    let Some(site) = site else {
        return Err(missing_marker());
    };
    let lookup = site
        .sizes()
        .lookup(payload)
        .ok_or_else(|| unknown_marker_size(Some(site), payload).with_field(payload_pointer))?;
    let marker = Marker::try_new(lookup.size_mm).map_err(|e| {
        Problem::new(ErrorCode::InvalidMarkerSize, e.to_string()).with_field(MARKER_POINTER)
    })?;
    Ok((marker, lookup.source))
}

/// The refusal of a request without a marker size and without a site to give one.
pub fn missing_marker() -> Problem {
    Problem::new(
        ErrorCode::MissingField,
        "the marker size is required: give marker.size_mm (marker_size_mm), or load a site \
         (qrpose serve --site) that sizes the code",
    )
    .with_field(MARKER_POINTER)
}

/// The problem of a code the site has no size for (or, without a site, a code whose
/// request gave no size).
pub fn unknown_marker_size(site: Option<&Site>, payload: Option<&str>) -> Problem {
    let which = match payload {
        Some(p) => format!("payload {p:?}"),
        None => "an undecoded code".to_owned(),
    };
    let detail = match site {
        Some(site) => format!(
            "no marker size for {which}: the request gives none and the site {} has no rule \
             for it and no default_size_mm",
            site.file().display()
        ),
        None => format!("no marker size for {which}: the request gives none and no site is loaded"),
    };
    Problem::new(ErrorCode::UnknownMarkerSize, detail)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn site() -> Site {
        let text = "cameras:\n  front:\n    intrinsics: {fx_px: 900, fy_px: 900, cx_px: 320, cy_px: 240}\n\
                    markers:\n  sizes:\n    - {prefix: \"LOC-\", size_mm: 80}\n";
        Site::parse(text, Path::new("site.yaml")).expect("a valid site")
    }

    fn id(id: &str) -> CameraDto {
        CameraDto {
            id: Some(id.to_owned()),
            ..CameraDto::default()
        }
    }

    #[test]
    fn a_camera_id_resolves_to_the_site_camera_or_its_refusal() {
        let site = site();
        let resolved = resolve_camera(&id("front"), CornersUnit::Px, Some(&site)).expect("known");
        assert_eq!(resolved.camera.fx(), 900.0);
        assert!(resolved.site_camera.is_some());
        let cases = [
            (
                id("roof"),
                CornersUnit::Px,
                Some(&site),
                ErrorCode::UnknownCamera,
                CAMERA_ID_POINTER,
            ),
            (
                id("front"),
                CornersUnit::Px,
                None,
                ErrorCode::UnknownCamera,
                CAMERA_ID_POINTER,
            ),
            (
                id("front"),
                CornersUnit::Mm,
                Some(&site),
                ErrorCode::IncompleteCamera,
                CAMERA_ID_POINTER,
            ),
            (
                CameraDto {
                    fx_px: Some(1.0),
                    ..id("front")
                },
                CornersUnit::Px,
                Some(&site),
                ErrorCode::IncompleteCamera,
                "/camera",
            ),
        ];
        for (dto, unit, site, code, field) in cases {
            let p = resolve_camera(&dto, unit, site).expect_err("refused");
            assert_eq!((p.code, p.field.as_deref()), (code, Some(field)), "{dto:?}");
        }
    }

    #[test]
    fn a_marker_size_comes_from_the_request_then_the_site() {
        let site = site();
        let request = MarkerDto { size_mm: 33.0 };
        let (m, source) =
            resolve_marker(Some(&request), Some(&site), Some("LOC-1"), "/payload").expect("sized");
        assert_eq!((m.size_mm(), source), (33.0, SizeSource::Request));
        let (m, source) =
            resolve_marker(None, Some(&site), Some("LOC-1"), "/payload").expect("sized");
        assert_eq!((m.size_mm(), source), (80.0, SizeSource::SitePrefix));
        let p = resolve_marker(None, Some(&site), Some("SKU-1"), "/payload").expect_err("unsized");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::UnknownMarkerSize, Some("/payload"))
        );
        let p = resolve_marker(None, None, Some("LOC-1"), "/payload").expect_err("no site");
        assert_eq!(
            (p.code, p.field.as_deref()),
            (ErrorCode::MissingField, Some(MARKER_POINTER))
        );
    }
}
