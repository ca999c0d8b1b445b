//! The built-in videos, by name ([`builtin_sequence`]): the rendered video of the stream's
//! measurements (docs/rendering.md), each a plain [`SequenceSpec`] (print it, edit it, load
//! it back). All 1280 × 720 at fx = fy = 1000 px, 30 fps, with a textured wall behind the
//! codes, lens blur, sensor noise, uneven lighting and JPEG quality 85; each has its own
//! seed, so the same name always gives the same pixels.
//!
//! - `approach`: a camera approaching a rack of six codes (three of 50 mm, three of 80 mm,
//!   each turned a few degrees) from 2 m to 0.4 m in 10 s, drifting sideways and ending
//!   square on one 80 mm code; a slight shake.
//! - `still`: a camera standing still for 5 s before four codes 0.4, 0.7, 1.0 and 1.5 m
//!   away, turned 10-35°: only the noise changes between frames (jitter).
//! - `pan`: a camera moving 3.2 m along a shelf 0.9 m away in 8 s, turning as it goes, so
//!   that eleven codes enter and leave the picture; two of them say the same (`SHELF-TWIN`)
//!   and are in view together; motion blur (6 ms exposure) and a slight shake.

use super::super::EcLevel;
use super::spec::{
    CameraSpec, EulerDeg, Interpolation, KeyframeSpec, SequenceEffects, SequenceSpec, Shake,
    TrajectorySpec, WallSpec, WorldCode,
};

/// The names [`builtin_sequence`] knows.
pub const BUILTIN_SEQUENCES: [&str; 3] = ["approach", "still", "pan"];

/// The built-in sequence called `name`, or `None` for a name not in [`BUILTIN_SEQUENCES`].
pub fn builtin_sequence(name: &str) -> Option<SequenceSpec> {
    match name {
        "approach" => Some(approach()),
        "still" => Some(still()),
        "pan" => Some(pan()),
        _ => None,
    }
}

fn code(
    payload: &str,
    size_mm: f64,
    position_mm: [f64; 3],
    [alpha, beta, gamma]: [f64; 3],
) -> WorldCode {
    WorldCode {
        payload: payload.to_owned(),
        ec_level: EcLevel::M,
        size_mm,
        position_mm,
        rotation_euler_xyz_deg: EulerDeg { alpha, beta, gamma },
    }
}

fn looking(time_ms: f64, position_mm: [f64; 3], look_at_mm: [f64; 3]) -> KeyframeSpec {
    KeyframeSpec {
        time_ms,
        position_mm,
        look_at_mm: Some(look_at_mm),
        roll_deg: 0.0,
        rotation_euler_xyz_deg: None,
    }
}

fn wall(z_mm: f64, size_mm: [f64; 2], shapes: u32) -> WallSpec {
    WallSpec {
        position_mm: [0.0, 0.0, z_mm],
        rotation_euler_xyz_deg: EulerDeg::default(),
        size_mm,
        level: 150.0,
        shapes,
    }
}

/// The effects every built-in shares (a typical webcam frame).
fn camera_effects() -> SequenceEffects {
    SequenceEffects {
        supersample: 3,
        blur_px: 0.7,
        noise: 2.0,
        lighting: 0.2,
        jpeg_quality: 85,
        ..SequenceEffects::default()
    }
}

fn spec(name: &str, codes: Vec<WorldCode>, trajectory: TrajectorySpec) -> SequenceSpec {
    SequenceSpec {
        name: name.to_owned(),
        width_px: 1280,
        height_px: 720,
        camera: CameraSpec::default(),
        fps: 30.0,
        frames: None,
        duration_ms: None,
        codes,
        trajectory,
        wall: None,
        effects: camera_effects(),
        seed: 0,
    }
}

fn approach() -> SequenceSpec {
    let codes = vec![
        code("RACK-A1", 80.0, [-260.0, -120.0, 2000.0], [3.0, 6.0, -4.0]),
        code("RACK-A2", 50.0, [0.0, -120.0, 2000.0], [-4.0, -5.0, 3.0]),
        code("RACK-A3", 80.0, [260.0, -120.0, 2000.0], [2.0, -8.0, 2.0]),
        code("RACK-B1", 50.0, [-260.0, 120.0, 2000.0], [-2.0, 7.0, 5.0]),
        code("RACK-B2", 80.0, [0.0, 120.0, 2000.0], [4.0, 4.0, -3.0]),
        code("RACK-B3", 50.0, [260.0, 120.0, 2000.0], [-3.0, -6.0, -5.0]),
    ];
    let trajectory = TrajectorySpec {
        keyframes: vec![
            looking(0.0, [-400.0, -60.0, 0.0], [-80.0, 0.0, 2000.0]),
            looking(3500.0, [-200.0, 40.0, 700.0], [-40.0, 10.0, 2000.0]),
            looking(7000.0, [40.0, 60.0, 1250.0], [0.0, 60.0, 2000.0]),
            looking(10000.0, [0.0, 120.0, 1600.0], [0.0, 120.0, 2000.0]),
        ],
        interpolation: Interpolation::Smooth,
        shake: Shake {
            position_mm: 0.3,
            rotation_deg: 0.03,
        },
    };
    SequenceSpec {
        duration_ms: Some(10_000.0),
        wall: Some(wall(2010.0, [2400.0, 1600.0], 60)),
        seed: 1,
        ..spec("approach", codes, trajectory)
    }
}

fn still() -> SequenceSpec {
    let codes = vec![
        code(
            "NEAR-400",
            50.0,
            [-120.0, -40.0, 400.0],
            [15.0, -25.0, 10.0],
        ),
        code("MID-700", 80.0, [150.0, 60.0, 700.0], [-20.0, 30.0, -15.0]),
        code(
            "FAR-1000",
            50.0,
            [-250.0, 120.0, 1000.0],
            [10.0, 10.0, 40.0],
        ),
        code(
            "FAR-1500",
            80.0,
            [300.0, -120.0, 1500.0],
            [-25.0, -20.0, 5.0],
        ),
    ];
    let trajectory = TrajectorySpec {
        keyframes: vec![KeyframeSpec {
            time_ms: 0.0,
            position_mm: [0.0, 0.0, 0.0],
            look_at_mm: None,
            roll_deg: 0.0,
            rotation_euler_xyz_deg: None,
        }],
        interpolation: Interpolation::Smooth,
        shake: Shake::default(),
    };
    SequenceSpec {
        duration_ms: Some(5000.0),
        wall: Some(wall(1700.0, [2400.0, 1600.0], 50)),
        seed: 2,
        ..spec("still", codes, trajectory)
    }
}

fn pan() -> SequenceSpec {
    // Eleven codes 300 mm apart along the shelf, on alternate rows, 80 and 50 mm by turns;
    // the two in the middle say the same.
    let codes = (0..11)
        .map(|i| {
            let x = -1500.0 + 300.0 * f64::from(i);
            let y = if i % 2 == 0 { -150.0 } else { 150.0 };
            let size = if i % 4 < 2 { 80.0 } else { 50.0 };
            let payload = if i == 4 || i == 6 {
                "SHELF-TWIN".to_owned()
            } else {
                format!("SHELF-{i:02}")
            };
            let turn = [
                f64::from(i % 3) * 4.0 - 4.0,
                f64::from(i % 5) * 3.0 - 6.0,
                0.0,
            ];
            code(&payload, size, [x, y, 900.0], turn)
        })
        .collect();
    let trajectory = TrajectorySpec {
        keyframes: vec![
            looking(0.0, [-1600.0, 0.0, 0.0], [-1300.0, 0.0, 900.0]),
            looking(4000.0, [0.0, -30.0, 50.0], [100.0, 0.0, 900.0]),
            looking(8000.0, [1600.0, 0.0, 0.0], [1500.0, 20.0, 900.0]),
        ],
        interpolation: Interpolation::Smooth,
        shake: Shake {
            position_mm: 0.5,
            rotation_deg: 0.05,
        },
    };
    SequenceSpec {
        duration_ms: Some(8000.0),
        wall: Some(wall(910.0, [4000.0, 1400.0], 120)),
        effects: SequenceEffects {
            shutter_ms: 6.0,
            motion_samples: 3,
            ..camera_effects()
        },
        seed: 3,
        ..spec("pan", codes, trajectory)
    }
}
