//! joints.csv: `frame,joint,x,y,z`, one row per joint per frame where the position is known.

use std::fmt::Write;

/// Rows ordered by frame (0-based index), then by joint in skeleton order; mm, 3 decimals.
pub(crate) fn write(skel: &bonefit::Skeleton) -> Vec<u8> {
    let mut out = String::from("frame,joint,x,y,z\n");
    for f in 0..skel.frame_count {
        for j in &skel.joints {
            let Some(p) = j
                .positions
                .get(f)
                .filter(|p| p.iter().all(|c| c.is_finite()))
            else {
                continue;
            };
            let r = |c: f64| crate::json::round(c, 3).unwrap_or(0.0);
            let _ = writeln!(
                out,
                "{f},{},{:.3},{:.3},{:.3}",
                j.name,
                r(p[0]),
                r(p[1]),
                r(p[2])
            );
        }
    }
    out.into_bytes()
}
