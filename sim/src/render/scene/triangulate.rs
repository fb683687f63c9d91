//! Ear-clipping triangulation of simple polygons (building roofs).

use glam::Vec2;

/// Ear-clipping triangulation of a simple polygon (either winding).
pub fn triangulate(poly: &[Vec2]) -> Vec<[usize; 3]> {
    let n = poly.len();
    if n < 3 {
        return Vec::new();
    }
    let area: f32 = (0..n).map(|i| poly[i].perp_dot(poly[(i + 1) % n])).sum();
    let sign = if area >= 0.0 { 1.0 } else { -1.0 };
    let mut idx: Vec<usize> = (0..n).collect();
    let mut out = Vec::new();
    let mut guard = 0;
    while idx.len() > 3 && guard < n * n {
        guard += 1;
        let m = idx.len();
        let mut clipped = false;
        for k in 0..m {
            let (a, b, c) = (idx[(k + m - 1) % m], idx[k], idx[(k + 1) % m]);
            let (pa, pb, pc) = (poly[a], poly[b], poly[c]);
            if (pb - pa).perp_dot(pc - pb) * sign <= 0.0 {
                continue;
            }
            let inside = idx.iter().any(|&q| {
                if q == a || q == b || q == c {
                    return false;
                }
                let p = poly[q];
                let d1 = (pb - pa).perp_dot(p - pa) * sign;
                let d2 = (pc - pb).perp_dot(p - pb) * sign;
                let d3 = (pa - pc).perp_dot(p - pc) * sign;
                d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0
            });
            if !inside {
                out.push([a, b, c]);
                idx.remove(k);
                clipped = true;
                break;
            }
        }
        if !clipped {
            break;
        }
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangulates_a_concave_l_shape() {
        let l = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 2.0),
            Vec2::new(0.0, 2.0),
        ];
        let tris = triangulate(&l);
        assert_eq!(tris.len(), 4);
        let area: f32 = tris
            .iter()
            .map(|&[a, b, c]| 0.5 * (l[b] - l[a]).perp_dot(l[c] - l[a]).abs())
            .sum();
        assert!((area - 3.0).abs() < 1e-5, "area {area}");
    }
}
