//! Merging a map's road mesh: real maps' road surfaces come as one quad per
//! metre of lane; where a strip of quads runs straight it is drawn as a few
//! long quads (fewer triangles to draw, the same ground covered).

use glam::Vec3;

use super::primitives::Tris;

/// Most a dropped rib's ends may lie off the straight edge that replaces them (metres).
const MERGE_TOLERANCE_M: f32 = 0.01;
/// Longest quad edge merging may make (metres): long quads clip badly in
/// lavapipe's fixed point.
const MERGE_MAX_SPAN_M: f32 = 25.0;

/// The ribs of a strip to keep: rib `i` runs from `a(i)` to `b(i)`, and
/// consecutive ribs bound one quad. An interior rib is dropped when both of
/// its ends, and those of every rib dropped since the last kept one, lie
/// within [`MERGE_TOLERANCE_M`] of the straight edges from the last kept rib
/// to the next one, and those edges are at most [`MERGE_MAX_SPAN_M`] long:
/// straight stretches become one quad, curves keep their samples. The first
/// and last ribs are always kept; non-finite points are never dropped.
pub(super) fn kept_ribs(
    n: usize,
    a: impl Fn(usize) -> Vec3,
    b: impl Fn(usize) -> Vec3,
) -> Vec<usize> {
    if n <= 2 {
        return (0..n).collect();
    }
    let off = |p: Vec3, s: Vec3, e: Vec3| {
        let d = e - s;
        let u = ((p - s).dot(d) / d.length_squared().max(1e-12)).clamp(0.0, 1.0);
        (s + d * u).distance(p)
    };
    let mut kept = vec![0];
    for i in 1..n - 1 {
        let last = kept[kept.len() - 1];
        let straight = |side: &dyn Fn(usize) -> Vec3| {
            let (s, e) = (side(last), side(i + 1));
            s.distance(e) <= MERGE_MAX_SPAN_M
                && (last + 1..=i).all(|j| off(side(j), s, e) <= MERGE_TOLERANCE_M)
        };
        if !(straight(&a) && straight(&b)) {
            kept.push(i);
        }
    }
    kept.push(n - 1);
    kept
}

/// Two triangles sharing an edge, as their quad's corners in boundary order;
/// `None` unless they share exactly one edge and lie on either side of it.
fn quad_of(t0: [u32; 3], t1: [u32; 3], pos: &[Vec3]) -> Option<[u32; 4]> {
    let distinct = |t: [u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    if !distinct(t0) || !distinct(t1) {
        return None;
    }
    let shared: Vec<u32> = t0.iter().copied().filter(|v| t1.contains(v)).collect();
    let [u, v] = shared[..] else {
        return None;
    };
    let p = t0.iter().copied().find(|x| !t1.contains(x))?;
    let q = t1.iter().copied().find(|x| !t0.contains(x))?;
    let at = |i: u32| pos[i as usize].truncate();
    let side = |x: u32| (at(v) - at(u)).perp_dot(at(x) - at(u));
    (side(p) * side(q) < 0.0).then_some([p, u, q, v])
}

/// Draws a triangle mesh, merging its quad strips (pairs of triangles
/// sharing an edge, consecutive quads sharing a side) where they run
/// straight (see [`kept_ribs`]); whatever is not part of a strip is drawn
/// as it is. Real maps' road surfaces come as one quad per metre of lane.
pub(super) fn merged_mesh(pos: &[Vec3], tris: &[[u32; 3]], t: &mut Tris, col: u32) {
    enum Piece {
        Quad([u32; 4]),
        Tri([u32; 3]),
    }
    let mut pieces = Vec::with_capacity(tris.len());
    let mut i = 0;
    while i < tris.len() {
        if let Some(q) = tris.get(i + 1).and_then(|&t1| quad_of(tris[i], t1, pos)) {
            pieces.push(Piece::Quad(q));
            i += 2;
        } else {
            pieces.push(Piece::Tri(tris[i]));
            i += 1;
        }
    }
    let p = |i: u32| pos[i as usize];
    // The rib after `rib` in quad `q` (its other side), ends matched along
    // the quad's edges; `None` unless `rib` is a side of `q`.
    let across = |q: [u32; 4], rib: [u32; 2]| {
        let j = q.iter().position(|&x| x == rib[0])?;
        if q[(j + 1) % 4] == rib[1] {
            Some([q[(j + 3) % 4], q[(j + 2) % 4]])
        } else if q[(j + 3) % 4] == rib[1] {
            Some([q[(j + 1) % 4], q[(j + 2) % 4]])
        } else {
            None
        }
    };
    let mut k = 0;
    while k < pieces.len() {
        let q = match pieces[k] {
            Piece::Tri([a, b, c]) => {
                t.tri(p(a), p(b), p(c), col);
                k += 1;
                continue;
            }
            Piece::Quad(q) => q,
        };
        k += 1;
        // The side shared with the next quad starts the strip's second rib.
        let start = match pieces.get(k) {
            Some(&Piece::Quad(next)) => (0..4).find_map(|j| {
                let rib = [q[j], q[(j + 1) % 4]];
                across(next, rib).and_then(|_| across(q, rib).map(|first| [first, rib]))
            }),
            _ => None,
        };
        let Some([first, second]) = start else {
            t.quad(p(q[0]), p(q[1]), p(q[2]), p(q[3]), col);
            continue;
        };
        let mut ribs = vec![first, second];
        while let Some(&Piece::Quad(next)) = pieces.get(k) {
            let Some(rib) = across(next, ribs[ribs.len() - 1]) else {
                break;
            };
            ribs.push(rib);
            k += 1;
        }
        let kept = kept_ribs(ribs.len(), |i| p(ribs[i][0]), |i| p(ribs[i][1]));
        for w in kept.windows(2) {
            let (r0, r1) = (ribs[w[0]], ribs[w[1]]);
            t.quad(p(r0[0]), p(r1[0]), p(r1[1]), p(r0[1]), col);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::scene::primitives::area;

    /// A lane-like strip: ribs `[left, right]` at each centre point, two
    /// triangles per quad as xodr emits them.
    fn strip_mesh(centre: &[Vec3], half_w: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for (i, p) in centre.iter().enumerate() {
            let (a, b) = (
                centre[i.saturating_sub(1)],
                centre[(i + 1).min(centre.len() - 1)],
            );
            let d = (b - a).normalize();
            let n = Vec3::new(-d.y, d.x, 0.0);
            pos.push(*p + n * half_w);
            pos.push(*p - n * half_w);
        }
        let mut tris = Vec::new();
        for i in 0..centre.len() as u32 - 1 {
            let (l0, r0, l1, r1) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            tris.push([l0, r0, r1]);
            tris.push([l0, r1, l1]);
        }
        (pos, tris)
    }

    #[test]
    fn straight_road_strips_merge_into_long_quads() {
        // 60 m of lane sampled every metre: 60 quads become 3 (25 m cap).
        let centre: Vec<Vec3> = (0..=60).map(|i| Vec3::new(i as f32, 5.0, 0.3)).collect();
        let (pos, tris) = strip_mesh(&centre, 1.75);
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        assert_eq!(t.v.len() / 6, 3, "quads after merging");
        assert!(
            (area(&t.v) - 60.0 * 3.5).abs() < 1e-2,
            "area {}",
            area(&t.v)
        );
        for v in &t.v {
            assert!((v.pos[2] - 0.3).abs() < 1e-6);
            assert!((v.pos[1] - 5.0).abs() - 1.75 < 1e-4, "{:?}", v.pos);
        }
    }

    /// A strip along an arc of `radius_m`, one sample per metre for 31 m:
    /// (quads after merging, area before, area after).
    fn merged_arc(radius_m: f32) -> (usize, f32, f32) {
        let centre: Vec<Vec3> = (0..=31)
            .map(|i| {
                let a = i as f32 / radius_m;
                Vec3::new(radius_m * a.cos(), radius_m * a.sin(), 0.0)
            })
            .collect();
        let (pos, tris) = strip_mesh(&centre, 1.75);
        let mut plain = Tris::default();
        for &[a, b, c] in &tris {
            plain.tri(pos[a as usize], pos[b as usize], pos[c as usize], 0);
        }
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        (t.v.len() / 6, area(&plain.v), area(&t.v))
    }

    #[test]
    fn curved_road_strips_keep_their_samples() {
        // Radius 20 m: the chord over two samples is 25 mm off the middle
        // one, more than the 10 mm tolerance: every rib stays.
        let (quads, a0, a1) = merged_arc(20.0);
        assert_eq!(quads, 31);
        assert!((a0 - a1).abs() < 1e-3, "{a0} vs {a1}");
        // Radius 400 m: chords up to ~5.6 m stay within 10 mm of the arc.
        let (quads, a0, a1) = merged_arc(400.0);
        assert!((5..=10).contains(&quads), "{quads} quads of 31");
        // The merged surface covers the same ground to within the tolerance.
        assert!((a0 - a1).abs() < 0.01 * 31.0 * 2.0, "{a0} vs {a1}");
    }

    #[test]
    fn lone_triangles_and_odd_pairs_are_drawn_as_they_are() {
        let pos = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(6.0, 5.0, 0.0),
            Vec3::new(5.0, 6.0, 0.0),
        ];
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        assert_eq!(t.v.len(), 6);
        assert!((area(&t.v) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn straight_sidewalks_merge() {
        let inner: Vec<Vec3> = (0..=40).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let outer: Vec<Vec3> = (0..=40).map(|i| Vec3::new(i as f32, 3.0, 0.0)).collect();
        assert_eq!(kept_ribs(41, |i| inner[i], |i| outer[i]), vec![0, 25, 40]);
        // A kink in the outer edge keeps its rib.
        let mut bent = outer.clone();
        bent[10].y = 3.5;
        let kept = kept_ribs(41, |i| inner[i], |i| bent[i]);
        assert!(kept.contains(&10), "{kept:?}");
        let mut nan = outer;
        nan[5].x = f32::NAN;
        assert!(kept_ribs(41, |i| inner[i], |i| nan[i]).contains(&5));
    }
}
