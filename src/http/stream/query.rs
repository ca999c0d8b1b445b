//! The query string of `GET /v1/stream`: the parameters of `POST /v1/pose/image`, with the
//! same names, meaning and refusals ([`ImageQuery`]), and the tracker's own
//! ([`TrackQuery`], each optional with a documented default).

use crate::api::image::ImageQuery;
use crate::api::stream::TrackQuery;
use crate::http::error::ApiError;
use crate::http::extract::parse_query;

/// The stream's query string split into the image request's parameters and the tracker's,
/// each parsed (a name the tracker does not know is the image request's, which refuses the
/// names it does not know either).
///
/// # Errors
/// As `POST /v1/pose/image`'s query: 400 `malformed_query`, 422 `unknown_field` … naming the
/// parameter.
pub fn split_query(query: Option<&str>) -> Result<(ImageQuery, TrackQuery), ApiError> {
    let names = TrackQuery::parameter_names();
    let mut image = form_urlencoded::Serializer::new(String::new());
    let mut track = form_urlencoded::Serializer::new(String::new());
    for (name, value) in form_urlencoded::parse(query.unwrap_or_default().as_bytes()) {
        let target = if names.iter().any(|n| *n == name) {
            &mut track
        } else {
            &mut image
        };
        target.append_pair(&name, &value);
    }
    let image = parse_query::<ImageQuery>(Some(&image.finish()))?;
    let track = parse_query::<TrackQuery>(Some(&track.finish()))?;
    Ok((image, track))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::problem::ErrorCode;

    #[test]
    fn the_query_splits_into_the_image_request_and_the_tracker() {
        let (image, track) = split_query(Some(
            "fx_px=900&coast_ms=250&marker_size_mm=40&full_search_every=3",
        ))
        .expect("valid");
        assert_eq!(image.fx_px, Some(900.0));
        assert_eq!(image.marker_size_mm, Some(40.0));
        assert_eq!(track.coast_ms, Some(250.0));
        assert_eq!(track.full_search_every, Some(3));
        let refused = split_query(Some("fx_px=900&coast=1")).expect_err("a typo");
        assert_eq!(refused.code(), ErrorCode::UnknownField);
        let no_names_in_common = ImageQuery::parameter_names()
            .iter()
            .all(|n| !TrackQuery::parameter_names().contains(n));
        assert!(no_names_in_common, "each name belongs to one of the two");
    }
}
