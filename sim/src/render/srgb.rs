//! sRGB's transfer function as two tables the shaders index, so that no pixel
//! depends on how a CPU approximates a power.
//!
//! The renderer shades in linear light. GPUs (and Mesa's llvmpipe) convert to
//! sRGB on store and back on load for `*Srgb` texture formats, but llvmpipe's
//! encode approximates `x^(1/2.4)` with the CPU's `rsqrtps`, whose low bits
//! differ between CPU makers (Mesa's `lp_build_linear_to_srgb`), and a shader's
//! `pow` is a polynomial of the compiler's choosing. So the renderer uses no
//! sRGB format and no `pow`: materials are decoded through [`decode_table`]
//! (the linear value of each 8-bit code), and the resolve pass encodes by
//! counting the [`encode_steps`] at or below a linear value, comparisons only.
//! Both tables are computed here in `f64` from IEC 61966-2-1's formulas and
//! rounded once to `f32`, so every machine uploads the same bits.

/// The linear value (0..1) of an sRGB-encoded value (0..1), IEC 61966-2-1.
pub fn decode(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB-encoded value (0..1) of a linear value (0..1), IEC 61966-2-1.
pub fn encode(l: f64) -> f64 {
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

/// The linear value of each 8-bit sRGB code, `decode(code / 255)`.
pub fn decode_table() -> [f32; 256] {
    std::array::from_fn(|c| decode(c as f64 / 255.0) as f32)
}

/// The linear values at which the 8-bit code steps up: entry `i` (0..255) is
/// where the encoded value reaches `(i + 0.5) / 255`, so the code of a linear
/// `x` is the number of entries at or below it (`round(255 * encode(x))`).
/// The last entry is `f32::MAX`, so no value counts past 255.
pub fn encode_steps() -> [f32; 256] {
    std::array::from_fn(|i| {
        if i == 255 {
            f32::MAX
        } else {
            decode((i as f64 + 0.5) / 255.0) as f32
        }
    })
}

/// The 8-bit code of a linear value by the resolve shader's rule: a binary
/// search counting the [`encode_steps`] at or below `x` (NaN and negatives
/// give 0, anything from the last step up 255).
pub fn encode_u8(steps: &[f32; 256], x: f32) -> u8 {
    let mut lo = 0usize;
    for half in [128, 64, 32, 16, 8, 4, 2, 1] {
        if x >= steps[lo + half - 1] {
            lo += half;
        }
    }
    lo as u8
}

/// Both tables as the shaders' uniform arrays (`array<vec4<f32>, 64>` each,
/// entry `i` at `[i / 4][i % 4]`): the decode table, then the steps.
pub fn uniform_bytes() -> Vec<u8> {
    let mut bytes = Vec::with_capacity(2 * 256 * 4);
    for v in decode_table().iter().chain(encode_steps().iter()) {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_decodes_and_encodes_back_to_itself() {
        let (table, steps) = (decode_table(), encode_steps());
        for (c, &l) in table.iter().enumerate() {
            assert_eq!(encode_u8(&steps, l), c as u8, "code {c} (linear {l})");
        }
        assert_eq!(table[0], 0.0);
        assert_eq!(table[255], 1.0);
    }

    #[test]
    fn the_steps_encode_as_the_formula_rounds() {
        let steps = encode_steps();
        assert!(steps.windows(2).all(|w| w[0] < w[1]), "steps ascend");
        // A dense sweep of linear values, away from the exact half-way points.
        for i in 0..=200_000 {
            let x = i as f64 / 200_000.0;
            let exact = 255.0 * encode(x);
            if (exact - exact.floor() - 0.5).abs() < 1e-4 {
                continue;
            }
            assert_eq!(
                encode_u8(&steps, x as f32),
                exact.round() as u8,
                "linear {x}"
            );
        }
        assert_eq!(encode_u8(&steps, -1.0), 0);
        assert_eq!(encode_u8(&steps, f32::NAN), 0);
        assert_eq!(encode_u8(&steps, 7.5), 255);
    }

    #[test]
    fn the_uniform_holds_both_tables_in_order() {
        let bytes = uniform_bytes();
        assert_eq!(bytes.len(), 2048);
        let at = |i: usize| f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
        assert_eq!(at(255), 1.0);
        assert_eq!(at(256), encode_steps()[0]);
        assert_eq!(at(511), f32::MAX);
    }
}
