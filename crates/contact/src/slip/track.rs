//! Marker identities across frames: each dot of the reference set (found on the background, the
//! gel at rest) is looked for near where it was last seen (its rest position when it was not
//! seen in the previous frame), within a bounded radius; ambiguous matches are rejected rather
//! than guessed.
//!
//! A match is kept when the nearest dot is within the search radius, the second nearest is at
//! least `ambiguity_ratio` times farther, and no other marker claims the same dot. The search
//! radius is capped at half the marker pitch (the median nearest-neighbour distance of the
//! reference), where a wrong neighbour would become the nearer one: a field that jumps more
//! than that in one frame cannot be tracked.

use super::markers::Dot;

/// The markers of the gel at rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    pub points: Vec<[f64; 2]>,
    pub width: u32,
    pub height: u32,
    /// Median distance from a marker to its nearest neighbour \[px] (0 with fewer than 2).
    pub pitch_px: f64,
}

impl Reference {
    pub fn new(dots: &[Dot], width: u32, height: u32) -> Self {
        let points: Vec<[f64; 2]> = dots.iter().map(|d| d.centre).collect();
        let mut nearest: Vec<f64> = points
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                points
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, q)| dist(*p, *q))
                    .min_by(f64::total_cmp)
            })
            .collect();
        nearest.sort_by(f64::total_cmp);
        let pitch_px = nearest.get(nearest.len() / 2).copied().unwrap_or(0.0);
        Self {
            points,
            width,
            height,
            pitch_px,
        }
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// How matches are made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Search radius around the predicted position \[px] (capped at half the pitch).
    pub search_px: f64,
    /// The second-nearest dot must be this many times farther than the nearest.
    pub ambiguity_ratio: f64,
}

/// For each reference marker, its position in this frame (None: not found or ambiguous), looked
/// for around `predicted` (one per reference marker).
pub fn track(
    reference: &Reference,
    predicted: &[[f64; 2]],
    dots: &[Dot],
    p: &TrackParams,
) -> Vec<Option<[f64; 2]>> {
    let radius = if reference.pitch_px > 0.0 {
        p.search_px.min(0.5 * reference.pitch_px)
    } else {
        p.search_px
    };
    let mut best: Vec<Option<usize>> = predicted
        .iter()
        .map(|&q| {
            let (mut d1, mut d2, mut j1) = (f64::INFINITY, f64::INFINITY, None);
            for (j, d) in dots.iter().enumerate() {
                let e = dist(q, d.centre);
                if e < d1 {
                    (d2, d1, j1) = (d1, e, Some(j));
                } else if e < d2 {
                    d2 = e;
                }
            }
            j1.filter(|_| d1 <= radius && d2 >= p.ambiguity_ratio * d1)
        })
        .collect();
    // A dot claimed by two markers belongs to neither.
    let mut claims = vec![0u32; dots.len()];
    for j in best.iter().flatten() {
        claims[*j] += 1;
    }
    for b in &mut best {
        if b.is_some_and(|j| claims[j] > 1) {
            *b = None;
        }
    }
    best.into_iter()
        .map(|b| b.map(|j| dots[j].centre))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(shift: [f64; 2]) -> Vec<Dot> {
        (0..5)
            .flat_map(|j| {
                (0..6).map(move |i| Dot {
                    centre: [
                        12.0 + 24.0 * i as f64 + shift[0],
                        12.0 + 24.0 * j as f64 + shift[1],
                    ],
                    area_px: 30,
                })
            })
            .collect()
    }
    const P: TrackParams = TrackParams {
        search_px: 20.0,
        ambiguity_ratio: 2.0,
    };

    #[test]
    fn a_shifted_field_is_followed_and_the_pitch_is_measured() {
        let r = Reference::new(&grid([0.0; 2]), 160, 120);
        assert!((r.pitch_px - 24.0).abs() < 1e-12);
        let moved = grid([3.5, -2.0]);
        let t = track(&r, &r.points, &moved, &P);
        for (got, want) in t.iter().zip(&moved) {
            assert_eq!(*got, Some(want.centre));
        }
    }

    #[test]
    fn half_a_pitch_is_ambiguous_and_more_is_out_of_reach() {
        let r = Reference::new(&grid([0.0; 2]), 160, 120);
        // 11 px: the dot of the marker to the left is 13 px away, within 2x: rejected, not
        // guessed. Only the first column (no marker to its left) is matched, rightly.
        let moved = grid([11.0, 0.0]);
        let t = track(&r, &r.points, &moved, &P);
        for (i, got) in t.iter().enumerate() {
            let want = (i % 6 == 0).then_some(moved[i].centre);
            assert_eq!(*got, want, "{i}");
        }
        // 13 px: the neighbour's dot is the nearer one (11 px): rejected, never taken.
        let moved = grid([13.0, 0.0]);
        let t = track(&r, &r.points, &moved, &P);
        assert!(t.iter().all(Option::is_none), "{t:?}");
        // Followed frame to frame (prediction = last position), the same 13 px are tracked.
        let last: Vec<[f64; 2]> = grid([8.0, 0.0]).iter().map(|d| d.centre).collect();
        let t = track(&r, &last, &moved, &P);
        assert!(t.iter().zip(&moved).all(|(g, m)| *g == Some(m.centre)));
    }

    #[test]
    fn a_dot_two_markers_want_goes_to_neither() {
        let r = Reference::new(&grid([0.0; 2]), 160, 120);
        let mut dots = grid([0.0; 2]);
        dots.remove(1);
        // Markers 0 and 1 both predicted next to dot 0.
        let mut pred = r.points.clone();
        pred[1] = [14.0, 12.0];
        let t = track(&r, &pred, &dots, &P);
        assert_eq!((t[0], t[1]), (None, None));
        assert_eq!(t[2], Some(dots[1].centre));
    }
}
