//! One 8×8 block between coefficients and samples: zigzag order, (de)quantization, a float
//! inverse and forward DCT (ITU T.81 A.3.3; only the blocks the overlay touches go through
//! them), and the JFIF colour equations.

use std::f32::consts::{FRAC_1_SQRT_2, SQRT_2};

/// Coefficients of one block in zigzag order, as the entropy coding reads and writes them.
pub type Coefficients = [i32; 64];

/// The natural index of the k-th coefficient in zigzag order.
pub const ZIGZAG: [u8; 64] = [
    0, 1, 8, 16, 9, 2, 3, 10, 17, 24, 32, 25, 18, 11, 4, 5, 12, 19, 26, 33, 40, 48, 41, 34, 27, 20,
    13, 6, 7, 14, 21, 28, 35, 42, 49, 56, 57, 50, 43, 36, 29, 22, 15, 23, 30, 37, 44, 51, 58, 59,
    52, 45, 38, 31, 39, 46, 53, 60, 61, 54, 47, 55, 62, 63,
];

/// The largest magnitude of a quantized AC coefficient of 8-bit samples (size category 10).
const MAX_AC: i32 = 1023;
/// The largest magnitude of a quantized DC coefficient of 8-bit samples.
const MAX_DC: i32 = 1023;

/// Eight values, one per lane: the same 1-D transform runs on eight rows or columns.
type Lanes = [f32; 8];
/// An 8×8 block, row by row.
type Matrix = [Lanes; 8];

#[inline(always)]
fn add(a: Lanes, b: Lanes) -> Lanes {
    std::array::from_fn(|i| a[i] + b[i])
}

#[inline(always)]
fn sub(a: Lanes, b: Lanes) -> Lanes {
    std::array::from_fn(|i| a[i] - b[i])
}

#[inline(always)]
fn scale(a: Lanes, k: f32) -> Lanes {
    a.map(|v| v * k)
}

/// The transpose of `m`.
#[inline(always)]
fn transpose(m: &Matrix) -> Matrix {
    std::array::from_fn(|i| std::array::from_fn(|j| m[j][i]))
}

/// The 1-D forward DCT of Arai, Agui and Nakajima down the rows of `d` (libjpeg's
/// jfdctflt.c): output k is the DCT coefficient scaled by √8 · aan(k) (see [`AAN`]).
#[inline(always)]
fn forward(d: &Matrix) -> Matrix {
    let (tmp0, tmp7) = (add(d[0], d[7]), sub(d[0], d[7]));
    let (tmp1, tmp6) = (add(d[1], d[6]), sub(d[1], d[6]));
    let (tmp2, tmp5) = (add(d[2], d[5]), sub(d[2], d[5]));
    let (tmp3, tmp4) = (add(d[3], d[4]), sub(d[3], d[4]));
    // Even part.
    let (tmp10, tmp13) = (add(tmp0, tmp3), sub(tmp0, tmp3));
    let (tmp11, tmp12) = (add(tmp1, tmp2), sub(tmp1, tmp2));
    let z1 = scale(add(tmp12, tmp13), FRAC_1_SQRT_2);
    // Odd part.
    let (tmp10b, tmp11b, tmp12b) = (add(tmp4, tmp5), add(tmp5, tmp6), add(tmp6, tmp7));
    let z5 = scale(sub(tmp10b, tmp12b), 0.382_683_43);
    let z2 = add(scale(tmp10b, 0.541_196_1), z5);
    let z4 = add(scale(tmp12b, 1.306_563), z5);
    let z3 = scale(tmp11b, FRAC_1_SQRT_2);
    let (z11, z13) = (add(tmp7, z3), sub(tmp7, z3));
    [
        add(tmp10, tmp11),
        add(z11, z4),
        add(tmp13, z1),
        sub(z13, z2),
        sub(tmp10, tmp11),
        add(z13, z2),
        sub(tmp13, z1),
        sub(z11, z4),
    ]
}

/// The 1-D inverse DCT of Arai, Agui and Nakajima down the rows of `d` (libjpeg's
/// jidctflt.c), for inputs scaled by aan(k) (see [`AAN`]): outputs scaled by √8.
#[inline(always)]
fn inverse(d: &Matrix) -> Matrix {
    // Even part.
    let (tmp10, tmp11) = (add(d[0], d[4]), sub(d[0], d[4]));
    let tmp13 = add(d[2], d[6]);
    let tmp12 = sub(scale(sub(d[2], d[6]), SQRT_2), tmp13);
    let (tmp0, tmp3) = (add(tmp10, tmp13), sub(tmp10, tmp13));
    let (tmp1, tmp2) = (add(tmp11, tmp12), sub(tmp11, tmp12));
    // Odd part.
    let (z13, z10) = (add(d[5], d[3]), sub(d[5], d[3]));
    let (z11, z12) = (add(d[1], d[7]), sub(d[1], d[7]));
    let tmp7 = add(z11, z13);
    let tmp11b = scale(sub(z11, z13), SQRT_2);
    let z5 = scale(add(z10, z12), 1.847_759);
    let tmp10b = sub(scale(z12, 1.082_392_2), z5);
    let tmp12b = add(scale(z10, -2.613_126), z5);
    let tmp6 = sub(tmp12b, tmp7);
    let tmp5 = sub(tmp11b, tmp6);
    let tmp4 = add(tmp10b, tmp5);
    [
        add(tmp0, tmp7),
        add(tmp1, tmp6),
        add(tmp2, tmp5),
        sub(tmp3, tmp4),
        add(tmp3, tmp4),
        sub(tmp2, tmp5),
        sub(tmp1, tmp6),
        sub(tmp0, tmp7),
    ]
}

/// The AAN scale of frequency k: 1 for k = 0, else √2 · cos(kπ/16).
const AAN: [f32; 8] = [
    1.0,
    1.387_039_8,
    1.306_562_9,
    1.175_875_6,
    1.0,
    0.785_694_96,
    0.541_196_1,
    0.275_899_38,
];

/// The 2-D DCT (ITU T.81 A.3.3) of 8-bit samples, with the AAN butterflies; the scale
/// factors fold into the quantization.
#[derive(Debug, Clone, Copy, Default)]
pub struct Transform;

/// 64 values as a matrix, row by row.
fn matrix(values: &[f32; 64]) -> Matrix {
    let mut m = [[0.0_f32; 8]; 8];
    for (row, chunk) in m.iter_mut().zip(values.chunks_exact(8)) {
        row.copy_from_slice(chunk);
    }
    m
}

/// aan(u) · aan(v) for the coefficient at natural index k = 8v + u.
fn aan(k: usize) -> f32 {
    AAN[(k / 8) % 8] * AAN[k % 8]
}

impl Transform {
    /// The samples (0-255 scale, unclamped, unrounded) of quantized `coefficients` under
    /// `quant`.
    pub fn samples(&self, coefficients: &Coefficients, quant: &Quantizer) -> [f32; 64] {
        if coefficients.iter().all(|&c| c == 0) {
            return [128.0; 64];
        }
        // Dequantized in zigzag order (a loop that vectorizes), then put in natural order.
        let mut dequantized = [0.0_f32; 64];
        for ((out, &c), &q) in dequantized
            .iter_mut()
            .zip(coefficients)
            .zip(&quant.dequantize)
        {
            *out = c as f32 * q;
        }
        let mut f = [0.0_f32; 64];
        for (&v, &n) in dequantized.iter().zip(&ZIGZAG) {
            f[usize::from(n) & 63] = v;
        }
        // Down the columns, then along the rows; each pass scales by √8.
        let s = transpose(&inverse(&transpose(&inverse(&matrix(&f)))));
        let mut samples = [0.0_f32; 64];
        for (out, &v) in samples.iter_mut().zip(s.as_flattened()) {
            *out = v / 8.0 + 128.0;
        }
        samples
    }

    /// The quantized coefficients of a block whose samples are all `value`: its DC alone,
    /// 8 · (value − 128).
    pub fn flat(&self, value: f32, quant: &Quantizer) -> Coefficients {
        let mut coefficients = [0_i32; 64];
        // The forward transform of a flat block is 64 · (value − 128) at DC.
        coefficients[0] = quantize(64.0 * (value - 128.0), quant.quantize[0], MAX_DC);
        coefficients
    }

    /// The quantized coefficients of `samples` (0-255 scale) under `quant`.
    pub fn coefficients(&self, samples: &[f32; 64], quant: &Quantizer) -> Coefficients {
        let shifted = matrix(&samples.map(|s| s - 128.0));
        // Down the columns, then along the rows; each pass scales by √8 · aan.
        let f = transpose(&forward(&transpose(&forward(&shifted))));
        let f = f.as_flattened();
        // Put in zigzag order, then quantized (a loop that vectorizes).
        let zigzag: [f32; 64] = ZIGZAG.map(|n| f[usize::from(n) & 63]);
        let mut coefficients = [0_i32; 64];
        for ((out, &value), &q) in coefficients.iter_mut().zip(&zigzag).zip(&quant.quantize) {
            *out = quantize(value, q, MAX_AC);
        }
        coefficients[0] = quantize(f[0], quant.quantize[0], MAX_DC);
        coefficients
    }
}

/// `value · reciprocal` rounded to the nearest integer (ties to even), within ±`limit`.
/// Adding 1.5 · 2²³ leaves the rounded integer in the low mantissa bits: no libm call and
/// no saturating cast, so the loops over a block vectorize.
#[inline]
fn quantize(value: f32, reciprocal: f32, limit: i32) -> i32 {
    const MAGIC: f32 = 12_582_912.0;
    let limit = limit as f32;
    let scaled = (value * reciprocal).max(-limit).min(limit);
    (scaled + MAGIC).to_bits().cast_signed() - 0x4B40_0000
}

/// A quantization table with the AAN scale factors folded in, for [`Transform`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantizer {
    /// In zigzag order: what a quantized coefficient is multiplied by before the inverse
    /// transform, q · aan(u) · aan(v).
    dequantize: [f32; 64],
    /// In zigzag order: what the forward transform's output is multiplied by before
    /// rounding, 1 / (8 · aan(u) · aan(v) · q).
    quantize: [f32; 64],
}

impl Quantizer {
    /// The quantizer of a DQT table (zigzag order).
    pub fn new(zigzag: &[u16; 64]) -> Self {
        let mut natural = [1.0_f32; 64];
        for (&q, &k) in zigzag.iter().zip(&ZIGZAG) {
            if let Some(slot) = natural.get_mut(usize::from(k)) {
                *slot = f32::from(q);
            }
        }
        let dequantize: [f32; 64] = std::array::from_fn(|k| natural[k] * aan(k));
        let quantize: [f32; 64] = std::array::from_fn(|k| 1.0 / (8.0 * aan(k) * natural[k]));
        let zigzag_order = |table: [f32; 64]| ZIGZAG.map(|n| table[usize::from(n) & 63]);
        Self {
            dequantize: zigzag_order(dequantize),
            quantize: zigzag_order(quantize),
        }
    }
}

/// ITU T.81 Annex K.1, table K.1: the typical luminance quantization table, natural order.
const TYPICAL_LUMA: [u16; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
];

/// ITU T.81 Annex K.1, table K.2: the typical chrominance quantization table, natural order.
const TYPICAL_CHROMA: [u16; 64] = [
    17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99, 24, 26, 56, 99, 99, 99, 99, 99,
    47, 66, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
    99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99, 99,
];

/// A chrominance quantization table (zigzag order, 8-bit) for a frame quantized with the
/// luminance table `luma` (zigzag order): the typical table, scaled as the typical
/// luminance table is to `luma` (the median ratio; IJG's quality scaling makes them all
/// alike).
pub fn chroma_table(luma: &[u16; 64]) -> [u16; 64] {
    let mut ratios: Vec<u32> = luma
        .iter()
        .zip(&ZIGZAG)
        .map(|(&q, &k)| {
            let typical = TYPICAL_LUMA.get(usize::from(k)).copied().unwrap_or(16);
            u32::from(q) * 100 / u32::from(typical)
        })
        .collect();
    ratios.sort_unstable();
    let scale = ratios.get(32).copied().unwrap_or(100);
    ZIGZAG.map(|k| {
        let typical = u32::from(TYPICAL_CHROMA.get(usize::from(k)).copied().unwrap_or(99));
        u16::try_from(((typical * scale + 50) / 100).clamp(1, 255)).unwrap_or(255)
    })
}

/// JFIF's YCbCr of an sRGB colour, (R, G, B) (full range, ITU T.871).
pub fn ycbcr(colour: [u8; 3]) -> [f32; 3] {
    let [r, g, b] = colour.map(f32::from);
    [
        0.299 * r + 0.587 * g + 0.114 * b,
        -0.168_736 * r - 0.331_264 * g + 0.5 * b + 128.0,
        0.5 * r - 0.418_688 * g - 0.081_312 * b + 128.0,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DCT by definition (ITU T.81 A.3.3), in f64.
    fn reference(samples: &[f32; 64]) -> [f64; 64] {
        let c = |k: usize| {
            if k == 0 {
                std::f64::consts::FRAC_1_SQRT_2
            } else {
                1.0
            }
        };
        let pi = std::f64::consts::PI;
        std::array::from_fn(|k| {
            let (v, u) = (k / 8, k % 8);
            let mut sum = 0.0;
            for y in 0..8 {
                for x in 0..8 {
                    sum += (f64::from(samples[y * 8 + x]) - 128.0)
                        * (((2 * x + 1) * u) as f64 * pi / 16.0).cos()
                        * (((2 * y + 1) * v) as f64 * pi / 16.0).cos();
                }
            }
            c(u) * c(v) / 4.0 * sum
        })
    }

    #[test]
    fn the_forward_transform_is_the_dct() {
        let samples: [f32; 64] = std::array::from_fn(|i| ((i * 37 + i * i) % 256) as f32);
        let quant = Quantizer::new(&[1; 64]);
        let coefficients = Transform.coefficients(&samples, &quant);
        let reference = reference(&samples);
        for (k, (&got, &n)) in coefficients.iter().zip(&ZIGZAG).enumerate() {
            let want = reference[usize::from(n)];
            assert!(
                (f64::from(got) - want).abs() <= 0.51,
                "{k}: {got} against {want:.3}"
            );
        }
        // And the inverse gives the samples back.
        let back = Transform.samples(&coefficients, &quant);
        for (a, b) in samples.iter().zip(&back) {
            assert!((a - b).abs() <= 1.0, "{a} against {b}");
        }
    }

    #[test]
    fn the_transforms_invert_each_other() {
        let transform = Transform;
        let quant = Quantizer::new(&[1; 64]);
        let samples: [f32; 64] = std::array::from_fn(|i| ((i * 37) % 256) as f32);
        let coefficients = transform.coefficients(&samples, &quant);
        let back = transform.samples(&coefficients, &quant);
        for (a, b) in samples.iter().zip(&back) {
            assert!((a - b).abs() <= 1.0, "{a} against {b}");
        }
    }

    #[test]
    fn a_flat_block_has_only_its_dc_coefficient() {
        let transform = Transform;
        let coefficients = transform.coefficients(&[200.0; 64], &Quantizer::new(&[2; 64]));
        assert_eq!(coefficients[0], 288, "8 × (200 − 128) / 2");
        assert!(coefficients[1..].iter().all(|&c| c == 0));
    }

    #[test]
    fn grey_has_neutral_chroma() {
        let [y, cb, cr] = ycbcr([90, 90, 90]);
        assert!((y - 90.0).abs() < 1e-3 && (cb - 128.0).abs() < 1e-3 && (cr - 128.0).abs() < 1e-3);
    }
}
