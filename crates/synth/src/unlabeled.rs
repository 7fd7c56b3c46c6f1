//! A trial as an unlabeled reconstruction gives it: every marker's trajectory cut at each
//! of its gaps into a track of its own, the tracks in a shuffled order, so no label or
//! position in the list says which pieces are one marker (what `mocap-io.stitch` undoes).

use mocap_io::{MISSING, Trajectories};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

/// The pieces of `t`, shuffled by `seed`, and each piece's marker (index into `t`). Piece
/// `i`, the `k`-th (from 0, in time) of marker `label`, is named `name(i, label, k)`.
pub fn unlabeled(
    t: &Trajectories,
    seed: u64,
    name: impl Fn(usize, &str, usize) -> String,
) -> (Trajectories, Vec<usize>) {
    // (marker, its k-th piece, frames)
    let mut pieces: Vec<(usize, usize, std::ops::Range<usize>)> = Vec::new();
    for m in 0..t.markers() {
        let (mut f, mut k) = (0, 0);
        while f < t.frames() {
            if t.get(f, m).is_none() {
                f += 1;
                continue;
            }
            let start = f;
            while f < t.frames() && t.get(f, m).is_some() {
                f += 1;
            }
            pieces.push((m, k, start..f));
            k += 1;
        }
    }
    pieces.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let n = pieces.len();
    let mut positions = vec![MISSING; t.frames() * n];
    for (i, (m, _, frames)) in pieces.iter().enumerate() {
        for f in frames.clone() {
            positions[f * n + i] = t.frame(f)[*m];
        }
    }
    let labels = pieces
        .iter()
        .enumerate()
        .map(|(i, (m, k, _))| name(i, &t.labels()[*m], *k))
        .collect();
    let cut = Trajectories::new(
        labels,
        t.frame_rate(),
        t.first_frame(),
        t.frames(),
        positions,
    )
    .expect("pieces of valid trajectories are valid");
    (cut, pieces.iter().map(|p| p.0).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stretch_a_marker_is_seen_is_a_piece_of_its_own() {
        let nan = [f64::NAN; 3];
        // Marker A seen in frames 0-1 and 3; marker B in 0-3.
        let positions = vec![
            [1.0, 0.0, 0.0],
            [5.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [5.0, 1.0, 0.0],
            nan,
            [5.0, 2.0, 0.0],
            [1.0, 3.0, 0.0],
            [5.0, 3.0, 0.0],
        ];
        let t = Trajectories::new(vec!["A".into(), "B".into()], 100.0, 1, 4, positions).unwrap();
        let (cut, marker) = unlabeled(&t, 3, |i, label, k| format!("{label}{k}/{i}"));
        assert_eq!(cut.markers(), 3);
        let mut names: Vec<String> = cut.labels().iter().map(|l| l[..2].to_owned()).collect();
        names.sort();
        assert_eq!(names, ["A0", "A1", "B0"]);
        for (i, label) in cut.labels().iter().enumerate() {
            let seen: Vec<usize> = (0..4).filter(|&f| cut.get(f, i).is_some()).collect();
            let expected = match &label[..2] {
                "A0" => vec![0, 1],
                "A1" => vec![3],
                _ => vec![0, 1, 2, 3],
            };
            assert_eq!(seen, expected, "{label}");
            assert_eq!(t.labels()[marker[i]], label[..1]);
            for &f in &seen {
                assert_eq!(cut.get(f, i), t.get(f, marker[i]));
            }
        }
    }
}
