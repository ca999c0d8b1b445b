//! The built-in videos (`approach`, `still`, `pan`): what their truth promises (codes in
//! view in most frames, the distances, the camera standing still, two codes that say the
//! same in one frame), one full-size frame of each read by the detector where the truth
//! says the codes are; and the YUV4MPEG2 writer's header and frame layout.

use qrpose_detect::decode::GrayImage;
use qrpose_detect::{DetectorChoice, detect_codes};
use qrpose_sim::render::sequence::{
    FrameTruth, Sequence, Y4mColour, Y4mError, Y4mWriter, builtin_sequence, y4m_frame_bytes,
    y4m_header,
};

fn sequence(name: &str) -> Sequence {
    Sequence::new(builtin_sequence(name).expect("built-in")).expect("valid")
}

fn all_truth(seq: &Sequence) -> Vec<FrameTruth> {
    (0..seq.frame_count())
        .map(|k| seq.truth(k).expect("frame"))
        .collect()
}

/// The distance from the camera to a code's centre, mm.
fn distance_mm(position_mm: [f64; 3]) -> f64 {
    position_mm.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Renders frame `k` and checks that every code entirely in view with a side of at least
/// `min_side_px` is read, and that each code read lies where the truth puts a code with its
/// payload (every corner within 2 px).
fn read_where_the_truth_says(seq: &Sequence, k: u32, min_side_px: f64) {
    let frame = seq.render_frame(k).expect("renders");
    let found = detect_codes(&frame.image, DetectorChoice::Auto).expect("detector");
    let expected: Vec<_> = frame
        .truth
        .codes
        .iter()
        .filter(|c| c.fully_in_view && c.side_px >= min_side_px)
        .collect();
    assert!(!expected.is_empty(), "frame {k} has readable codes");
    for want in &expected {
        let centre = |c: &[[f64; 2]; 4]| {
            [
                c.iter().map(|p| p[0]).sum::<f64>() / 4.0,
                c.iter().map(|p| p[1]).sum::<f64>() / 4.0,
            ]
        };
        let w = centre(&want.truth.corners_px);
        let hit = found.iter().find(|f| {
            let corners = f.corners_px().map(|p| [p.u(), p.v()]);
            let c = centre(&corners);
            f.candidate.payload.as_deref() == Some(want.payload.as_bytes())
                && (c[0] - w[0]).hypot(c[1] - w[1]) < want.side_px / 2.0
        });
        let hit = hit.unwrap_or_else(|| panic!("frame {k}: {} not read", want.payload));
        for (p, q) in hit.corners_px().iter().zip(&want.truth.corners_px) {
            let error = (p.u() - q[0]).hypot(p.v() - q[1]);
            assert!(
                error < 2.0,
                "frame {k} {}: corner off by {error} px",
                want.payload
            );
        }
    }
}

#[test]
fn approach_closes_in_from_two_metres_to_forty_centimetres_with_codes_in_view() {
    let seq = sequence("approach");
    assert_eq!(seq.frame_count(), 300, "10 s at 30 fps");
    let truth = all_truth(&seq);
    let with_full = truth
        .iter()
        .filter(|t| t.codes.iter().any(|c| c.fully_in_view));
    assert!(
        with_full.count() >= 285,
        "a code entirely in view in 95 % of frames"
    );
    let nearest = |t: &FrameTruth| {
        t.codes
            .iter()
            .map(|c| distance_mm(c.truth.position_mm))
            .fold(f64::INFINITY, f64::min)
    };
    let (first, last) = (nearest(&truth[0]), nearest(&truth[299]));
    assert!((1900.0..2100.0).contains(&first), "starts {first} mm away");
    assert!((380.0..450.0).contains(&last), "ends {last} mm away");
    let sizes: Vec<f64> = truth[0].codes.iter().map(|c| c.size_mm).collect();
    assert!(sizes.contains(&50.0) && sizes.contains(&80.0) && sizes.len() == 6);
    read_where_the_truth_says(&seq, 150, 40.0);
}

#[test]
fn still_stands_still_before_codes_from_forty_centimetres_to_a_metre_and_a_half() {
    let seq = sequence("still");
    let truth = all_truth(&seq);
    assert_eq!(truth.len(), 150);
    for t in &truth {
        assert_eq!(t.camera, truth[0].camera, "frame {}", t.index);
        assert_eq!(t.codes, truth[0].codes, "frame {}", t.index);
    }
    let mut distances: Vec<f64> = truth[0]
        .codes
        .iter()
        .inspect(|c| assert!(c.fully_in_view))
        .map(|c| distance_mm(c.truth.position_mm))
        .collect();
    distances.sort_by(f64::total_cmp);
    assert!(distances.len() == 4 && distances[0] < 450.0 && distances[3] > 1400.0);
    // Only the noise differs between frames.
    let (a, b) = (
        seq.render_frame(0).expect("a"),
        seq.render_frame(1).expect("b"),
    );
    assert_ne!(a.image, b.image);
    read_where_the_truth_says(&seq, 0, 40.0);
}

#[test]
fn pan_brings_codes_in_and_out_with_two_that_say_the_same_in_one_frame() {
    let seq = sequence("pan");
    let truth = all_truth(&seq);
    assert_eq!(truth.len(), 240);
    let with_full = truth
        .iter()
        .filter(|t| t.codes.iter().any(|c| c.fully_in_view));
    assert!(
        with_full.count() >= 228,
        "a code entirely in view in 95 % of frames"
    );
    // Every code enters and leaves: seen, and not seen, in some frame.
    for i in 0..seq.spec().codes.len() {
        let seen = truth
            .iter()
            .filter(|t| t.codes.iter().any(|c| c.code_index == i));
        let count = seen.count();
        assert!(
            count > 0 && count < truth.len(),
            "code {i} in {count} frames"
        );
    }
    let twins = truth
        .iter()
        .filter(|t| {
            let twins = t
                .codes
                .iter()
                .filter(|c| c.payload == "SHELF-TWIN" && c.fully_in_view);
            twins.count() == 2
        })
        .count();
    assert!(twins >= 30, "both twins in view together in {twins} frames");
    read_where_the_truth_says(&seq, 100, 40.0);
}

fn grey(width: usize, height: usize, level: u8) -> GrayImage {
    GrayImage::new(width, height, vec![level; width * height]).expect("image")
}

#[test]
fn y4m_has_the_header_chromium_reads_and_whole_frames() {
    let header = y4m_header(64, 48, 30.0, Y4mColour::C420jpeg);
    assert_eq!(header, "YUV4MPEG2 W64 H48 F30:1 Ip A1:1 C420jpeg\n");
    assert_eq!(
        y4m_header(64, 48, 29.97, Y4mColour::Mono),
        "YUV4MPEG2 W64 H48 F2997:100 Ip A1:1 Cmono\n"
    );
    let mut writer = Y4mWriter::new(Vec::new(), 64, 48, 30.0, Y4mColour::C420jpeg).expect("header");
    for level in [10, 20, 30] {
        writer.write_frame(&grey(64, 48, level)).expect("frame");
    }
    let refused = writer.write_frame(&grey(48, 64, 0));
    assert!(matches!(refused, Err(Y4mError::FrameSize { .. })));
    let bytes = writer.finish().expect("flushed");
    let frame = y4m_frame_bytes(64, 48, Y4mColour::C420jpeg);
    assert_eq!(frame, 64 * 48 * 3 / 2);
    assert_eq!(bytes.len(), header.len() + 3 * (6 + frame));
    for (i, level) in [10u8, 20, 30].into_iter().enumerate() {
        let start = header.len() + i * (6 + frame);
        assert_eq!(&bytes[start..start + 6], b"FRAME\n");
        let planes = &bytes[start + 6..start + 6 + frame];
        assert!(planes[..64 * 48].iter().all(|&y| y == level), "luma");
        assert!(planes[64 * 48..].iter().all(|&c| c == 128), "no colour");
    }
    // Odd sizes round the chroma planes up; mono has luma alone.
    assert_eq!(y4m_frame_bytes(5, 3, Y4mColour::C420jpeg), 15 + 2 * 3 * 2);
    assert_eq!(y4m_frame_bytes(5, 3, Y4mColour::Mono), 15);
}
