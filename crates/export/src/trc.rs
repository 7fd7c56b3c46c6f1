//! joints.trc and joints.c3d: the root point and every joint centre as virtual markers, so
//! OpenSim (and any marker tool: Mokka, Vicon Nexus, Visual3D, Motive, a C3D/TRC reader in
//! Python) opens the skeleton's motion as it opens a capture: to view it beside the
//! markers, or to drive a model's inverse kinematics from joint centres.

use crate::{Error, Inputs, Params};

/// The root point first (named as the BVH ROOT), then the joints in skeleton order, one
/// trajectory each; frame rate and first frame of the capture; mm, rounded to 0.001 like
/// skeleton.json; missing where a position is unknown (null in the JSON). With `y_up`,
/// (x, y, z) → (x, z, −y) as for the BVH: OpenSim's ground is Y-up.
pub(crate) fn joint_trajectories(
    input: &Inputs<'_>,
    params: &Params,
) -> Result<mocap_io::Trajectories, Error> {
    let skel = input.skeleton;
    // The BVH's checks (a frame rate, a sample per frame on every track) are the TRC's too.
    crate::bvh::children(skel)?;
    let frames = skel.frame_count;
    let tracks: Vec<&[[f64; 3]]> = std::iter::once(skel.root_positions.as_slice())
        .chain(skel.joints.iter().map(|j| j.positions.as_slice()))
        .collect();
    let labels: Vec<String> = std::iter::once(skel.root_name.clone())
        .chain(skel.joints.iter().map(|j| j.name.clone()))
        .collect();
    let mut positions = Vec::with_capacity(frames * tracks.len());
    for f in 0..frames {
        for track in &tracks {
            positions.push(sample(track[f], params.y_up));
        }
    }
    let trajectories = mocap_io::Trajectories::new(
        labels,
        skel.frame_rate,
        input.trajectories.first_frame(),
        frames,
        positions,
    )
    .map_err(|e| Error::Mismatch(format!("joint trajectories: {e}")))?;
    Ok(trajectories)
}

/// joints.c3d (or markers.c3d, `name`): the same trajectories as a C3D file (mocap-io's
/// writer: float, mm, missing samples with residual −1), for the tools biomechanics reads
/// C3D in (Visual3D, Nexus, Mokka, ezc3d). C3D counts frames from 1 to 65535: a capture
/// that starts below 1 or ends past 65535 is numbered from 1 here (the TRC keeps the
/// capture's numbers), and one longer than 65535 frames gets no C3D (`None`).
pub(crate) fn c3d(tracks: &mocap_io::Trajectories, name: &str) -> Result<Option<Vec<u8>>, Error> {
    const LAST: i64 = u16::MAX as i64;
    if !crate::fits_c3d(tracks) {
        return Ok(None);
    }
    let frames = tracks.frames() as i64;
    let first = tracks.first_frame();
    let renumbered;
    let tracks = if first >= 1 && first + frames - 1 <= LAST {
        tracks
    } else {
        renumbered = mocap_io::Trajectories::new(
            tracks.labels().to_vec(),
            tracks.frame_rate(),
            1,
            tracks.frames(),
            tracks.positions().to_vec(),
        )
        .map_err(|e| Error::Mismatch(format!("{name}: {e}")))?;
        &renumbered
    };
    mocap_io::c3d::write(tracks)
        .map(Some)
        .map_err(|e| Error::Mismatch(format!("{name}: {e}")))
}

/// One position as written: rounded like skeleton.json, rotated for `y_up`, missing
/// where any coordinate is unknown.
pub(crate) fn sample(p: [f64; 3], y_up: bool) -> [f64; 3] {
    let r = |c: f64| crate::json::round(c, 3);
    match (r(p[0]), r(p[1]), r(p[2])) {
        (Some(x), Some(y), Some(z)) if y_up => [x, z, if y == 0.0 { 0.0 } else { -y }],
        (Some(x), Some(y), Some(z)) => [x, y, z],
        _ => mocap_io::MISSING,
    }
}
