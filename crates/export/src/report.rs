//! report.html: skeleton.json for a person: what was found, drawn and tabulated, with the
//! things worth a second look, in one self-contained page (no script, no external file).

use std::fmt::Write;

use crate::json::{BodyJson, JointJson, SkeletonJson};

/// Side of each of the three projection panels, px.
const PANEL_PX: f64 = 260.0;
/// Empty border inside a panel, px.
const MARGIN_PX: f64 = 16.0;

/// The page: a summary line, the skeleton at its best-known frame in three orthographic
/// projections (the capture's own axes, one scale for all three), then tables of joints,
/// segments and markers, the label swaps undone and the topology's notes. Every text that
/// came from the capture (labels) is escaped; the bytes depend only on the document.
pub(crate) fn write(doc: &SkeletonJson) -> Vec<u8> {
    let mut out = String::with_capacity(16 * 1024);
    out.push_str(
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>ossify skeleton report</title>\n<style>\n\
         body{font-family:system-ui,sans-serif;margin:2em;color:#222}\n\
         table{border-collapse:collapse;margin:0.5em 0 1.5em}\n\
         th,td{border:1px solid #ccc;padding:0.25em 0.6em;text-align:left;vertical-align:top}\n\
         th{background:#f2f2f2}\ntd.num{text-align:right;font-variant-numeric:tabular-nums}\n\
         .warn{color:#a40}\nsvg{border:1px solid #ccc;margin-right:1em;background:#fcfcfc}\n\
         </style>\n</head>\n<body>\n<h1>Skeleton report</h1>\n",
    );
    summary(&mut out, doc);
    reader_warnings(&mut out, doc);
    drawing(&mut out, doc);
    joints(&mut out, doc);
    segments(&mut out, doc);
    markers(&mut out, doc);
    notes(&mut out, doc);
    settings(&mut out, doc);
    let _ = writeln!(
        out,
        "<p><small>{} {}, skeleton.json schema {}.</small></p>\n</body>\n</html>",
        escape(&doc.generator),
        escape(&doc.ossify_version),
        doc.schema_version
    );
    out.into_bytes()
}

/// Text safe inside HTML (and XML) elements and attribute values.
pub(crate) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A number with `decimals` places, or an en dash when unknown.
fn number(value: Option<f64>, decimals: usize) -> String {
    value
        .filter(|v| v.is_finite())
        .map_or_else(|| "–".to_owned(), |v| format!("{v:.decimals$}"))
}

fn summary(out: &mut String, doc: &SkeletonJson) {
    let frames = doc.frame_count;
    let seconds = if doc.frame_rate > 0.0 {
        frames as f64 / doc.frame_rate
    } else {
        f64::NAN
    };
    let _ = writeln!(
        out,
        "<p>{frames} frames at {} Hz ({} s, first frame {}), {} markers: {} segments, {} \
         joints, root segment {}; {} marker(s) in no segment, {} segment(s) outside the tree. \
         Positions in {} in the capture's own frame.</p>",
        number(Some(doc.frame_rate), 2),
        number(Some(seconds), 2),
        doc.first_frame,
        doc.markers.len(),
        doc.segments.len(),
        doc.joints.len(),
        doc.root_segment,
        doc.unassigned_markers.len(),
        doc.detached_segments.len(),
        escape(&doc.units),
    );
    let room: Vec<String> = doc.stationary_markers().into_iter().map(escape).collect();
    if !room.is_empty() {
        let held = if doc.bodies.iter().any(|b| doc.is_room(b)) {
            "a segment of their own that no skeleton holds"
        } else {
            "a segment of their own in this tree (a fixed base)"
        };
        let _ = writeln!(
            out,
            "<p>Markers that never move (the room's: floor or reference markers, stray \
             reflections; or a fixed base's): {}; {held}.</p>",
            room.join(", ")
        );
    }
    let bodies: Vec<&BodyJson> = doc.bodies.iter().filter(|b| !doc.is_room(b)).collect();
    if let Some(body) = doc.body.as_ref().filter(|_| bodies.len() > 1) {
        let others: Vec<String> = bodies
            .iter()
            .filter(|b| &b.name != body)
            .map(|b| format!("{} ({} segments)", escape(&b.name), b.segments.len()))
            .collect();
        let _ = writeln!(
            out,
            "<p>The capture holds {} bodies, no joint between them: this is {}; the others, \
             {}, have skeletons of their own (<code>cargo xtask run</code> writes each into \
             the folder named after it inside its output folder, but its main body's, the \
             biggest by default, into the output folder itself).</p>",
            bodies.len(),
            escape(body),
            others.join(", ")
        );
    }
}

/// The frame with the most joint positions known (the earliest of those).
fn best_frame(doc: &SkeletonJson) -> Option<usize> {
    let known = |f: usize| {
        doc.joints
            .iter()
            .filter(|j| matches!(j.positions.get(f), Some(Some(_))))
            .count()
    };
    (0..doc.frame_count)
        .map(|f| (known(f), f))
        .filter(|&(k, _)| k > 0)
        .max_by(|a, b| a.0.cmp(&b.0).then(b.1.cmp(&a.1)))
        .map(|(_, f)| f)
}

/// The skeleton at its best-known frame, projected on the x–y, x–z and y–z planes: a line
/// from each joint to its parent joint (the root point for a joint of the root segment).
fn drawing(out: &mut String, doc: &SkeletonJson) {
    let Some(frame) = best_frame(doc) else {
        out.push_str("<p>No frame has a joint position to draw.</p>\n");
        return;
    };
    let at = |j: &JointJson| j.positions.get(frame).copied().flatten();
    let root = doc.root.positions.get(frame).copied().flatten();
    // (from, to, name of the joint at `to`)
    let mut bones: Vec<([f64; 3], [f64; 3], &str)> = Vec::new();
    let mut points: Vec<([f64; 3], &str)> = Vec::new();
    for j in &doc.joints {
        let Some(p) = at(j) else { continue };
        points.push((p, j.name.as_str()));
        let from = match &j.parent {
            Some(parent) => doc.joints.iter().find(|x| &x.name == parent).and_then(at),
            None => root,
        };
        if let Some(q) = from {
            bones.push((q, p, j.name.as_str()));
        }
    }
    if let Some(r) = root {
        points.push((r, doc.root.name.as_str()));
    }
    // One scale for the three views, from the largest extent on any axis.
    let lo = [0, 1, 2].map(|i| points.iter().map(|p| p.0[i]).fold(f64::INFINITY, f64::min));
    let hi = [0, 1, 2].map(|i| {
        points
            .iter()
            .map(|p| p.0[i])
            .fold(f64::NEG_INFINITY, f64::max)
    });
    let extent = (0..3).map(|i| hi[i] - lo[i]).fold(1.0, f64::max);
    let scale = (PANEL_PX - 2.0 * MARGIN_PX) / extent;
    let _ = writeln!(
        out,
        "<h2>Skeleton at frame {frame} (file frame {})</h2>\n<p>Orthographic views on the \
         capture's axes, one scale ({} mm across a panel); hover a joint for its name.</p>\n<div>",
        doc.first_frame + frame as i64,
        number(Some((PANEL_PX - 2.0 * MARGIN_PX) / scale), 0)
    );
    for (h, v, label) in [
        (0usize, 1usize, "x → right, y ↑"),
        (0, 2, "x → right, z ↑"),
        (1, 2, "y → right, z ↑"),
    ] {
        // Centred in the panel; screen y grows downwards, so the vertical axis is flipped.
        let inner = PANEL_PX - 2.0 * MARGIN_PX;
        let pad = |i: usize| MARGIN_PX + 0.5 * (inner - (hi[i] - lo[i]) * scale);
        let x = |p: &[f64; 3]| pad(h) + (p[h] - lo[h]) * scale;
        let y = |p: &[f64; 3]| PANEL_PX - pad(v) - (p[v] - lo[v]) * scale;
        let _ = write!(
            out,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{PANEL_PX}\" height=\"{PANEL_PX}\" \
             viewBox=\"0 0 {PANEL_PX} {PANEL_PX}\"><title>{label}</title>\
             <text x=\"4\" y=\"12\" font-size=\"10\" fill=\"#666\">{label}</text>"
        );
        for (a, b, _) in &bones {
            let _ = write!(
                out,
                "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#357\" stroke-width=\"2\"/>",
                x(a),
                y(a),
                x(b),
                y(b)
            );
        }
        for (p, name) in &points {
            let _ = write!(
                out,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"#c30\"><title>{}</title></circle>",
                x(p),
                y(p),
                escape(name)
            );
        }
        out.push_str("</svg>");
    }
    out.push_str("\n</div>\n");
}

fn joints(out: &mut String, doc: &SkeletonJson) {
    out.push_str(
        "<h2>Joints</h2>\n<table>\n<tr><th>joint</th><th>parent joint</th><th>segments \
         (parent → child)</th><th>kind</th><th>method</th><th>residual RMS, mm</th><th>residual \
         / noise</th><th>centre misfit, °</th><th>FK residual RMS, mm</th><th>range of motion, °</th><th>bone, mm</th><th>frames known \
         (interpolated)</th><th>warnings</th></tr>\n",
    );
    for j in &doc.joints {
        let warnings: Vec<String> = j.warnings.iter().map(|w| escape(w)).collect();
        let _ = writeln!(
            out,
            "<tr><td>{}</td><td>{}</td><td>{} → {}</td><td title=\"{}\">{}</td><td>{}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td>\
             <td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td class=\"num\">{} ({})</td><td class=\"warn\">{}</td></tr>",
            escape(&j.name),
            j.parent
                .as_deref()
                .map_or_else(|| escape(&doc.root.name), escape),
            j.parent_segment,
            j.child_segment,
            escape(&j.kind_evidence),
            escape(&j.kind),
            escape(&j.method),
            number(j.residual_rms_mm, 2),
            number(j.residual_over_noise, 2),
            number(j.centre_misfit_deg, 1),
            number(j.fk_residual_rms_mm, 2),
            number(j.range_of_motion_deg, 1),
            number(Some(j.bone_length_mm), 1),
            j.frames_known,
            j.frames_interpolated,
            warnings.join("<br>")
        );
    }
    out.push_str("</table>\n<p><small>Hover a kind for its evidence.</small></p>\n");
}

fn segments(out: &mut String, doc: &SkeletonJson) {
    out.push_str(
        "<h2>Segments</h2>\n<table>\n<tr><th>segment</th><th>markers</th><th>frames with a \
         pose</th><th>spin about the markers' line, °</th><th>maybe two (the joint test \
         came near cutting it)</th></tr>\n",
    );
    for s in &doc.segments {
        let labels: Vec<String> = s.markers.iter().map(|m| escape(m)).collect();
        let other_body = doc
            .bodies
            .iter()
            .find(|b| b.segments.contains(&s.id) && doc.body.as_ref() != Some(&b.name));
        let detached = if s.stationary && other_body.is_some() {
            " (markers that never move)".to_owned()
        } else if let Some(b) = other_body {
            format!(" ({}, another body)", escape(&b.name))
        } else if doc.detached_segments.contains(&s.id) {
            " <span class=\"warn\">(outside the tree)</span>".to_owned()
        } else if s.id == doc.root_segment {
            " (root)".to_owned()
        } else {
            String::new()
        };
        let near = s.near_joint.as_ref().map_or(String::new(), |n| {
            let part = |p: &[String]| p.iter().map(|m| escape(m)).collect::<Vec<_>>().join(", ");
            format!(
                "<span class=\"warn\">{} | {}</span> (rotation z {:.1}, travel z {:.1})",
                part(&n.parts[0]),
                part(&n.parts[1]),
                n.rotation_z,
                n.travel_z
            )
        });
        let _ = writeln!(
            out,
            "<tr><td>{}{detached}</td><td>{} ({})</td><td class=\"num\">{} of {}</td><td \
             class=\"num\">{}</td><td>{near}</td></tr>",
            s.id,
            labels.join(", "),
            s.marker_count,
            s.frames_with_pose,
            doc.frame_count,
            number(s.spin_deg, 1)
        );
    }
    out.push_str("</table>\n");
}

fn markers(out: &mut String, doc: &SkeletonJson) {
    out.push_str("<h2>Markers</h2>\n");
    let unassigned: Vec<_> = doc.markers.iter().filter(|m| m.segment.is_none()).collect();
    if unassigned.is_empty() {
        out.push_str("<p>Every marker is in a segment.</p>\n");
    } else {
        out.push_str("<table>\n<tr><th>marker in no segment</th><th>why</th></tr>\n");
        for m in unassigned {
            let _ = writeln!(
                out,
                "<tr><td>{}</td><td>{}</td></tr>",
                escape(&m.label),
                escape(m.unassigned_reason.as_deref().unwrap_or(""))
            );
        }
        out.push_str("</table>\n");
    }
    let sliding: Vec<String> = doc
        .markers
        .iter()
        .filter(|m| m.slides)
        .map(|m| {
            format!(
                "{} (segment {}, rigidity residual {} mm)",
                escape(&m.label),
                m.segment.map_or_else(|| "–".to_owned(), |s| s.to_string()),
                number(m.rigidity_residual_mm, 2)
            )
        })
        .collect();
    if !sliding.is_empty() {
        let _ = writeln!(
            out,
            "<p class=\"warn\">Sliding against their segment (skin or a loose marker): {}.</p>",
            sliding.join("; ")
        );
    }
    let filled: Vec<String> = doc
        .markers
        .iter()
        .filter(|m| m.filled_frames > 0)
        .map(|m| format!("{} ({})", escape(&m.label), m.filled_frames))
        .collect();
    if !filled.is_empty() {
        let _ = writeln!(
            out,
            "<p>markers.trc and markers.c3d fill {} missing samples from their segments' \
             poses: {}.</p>",
            doc.markers.iter().map(|m| m.filled_frames).sum::<usize>(),
            filled.join("; ")
        );
    }
    let glitching: Vec<String> = doc
        .markers
        .iter()
        .filter(|m| m.glitch_frames > 0)
        .map(|m| {
            let frames = crate::frame_count(m.glitch_frames);
            format!("{} ({frames})", escape(&m.label))
        })
        .collect();
    if !glitching.is_empty() {
        let _ = writeln!(
            out,
            "<p class=\"warn\">Jumped off their partners in some frames (a misreconstruction; \
             those samples are read as gaps): {}.</p>",
            glitching.join("; ")
        );
    }
    for swap in &doc.label_swaps {
        let spans: Vec<String> = swap
            .frames
            .iter()
            .map(|[a, b]| format!("{a}–{b}"))
            .collect();
        let _ = writeln!(
            out,
            "<p class=\"warn\">Labels {} and {} were exchanged in frames {} and are used \
             swapped back.</p>",
            escape(&swap.markers[0]),
            escape(&swap.markers[1]),
            spans.join(", ")
        );
    }
}

/// The parameters set away from their defaults, so a report says how it was made.
fn settings(out: &mut String, doc: &SkeletonJson) {
    if doc.settings.is_empty() {
        return;
    }
    out.push_str("<h2>Settings (--set)</h2>\n<ul>\n");
    for (name, value) in &doc.settings {
        let _ = writeln!(
            out,
            "<li><code>{}={}</code></li>",
            escape(name),
            escape(&value.to_string())
        );
    }
    out.push_str("</ul>\n");
}

/// What the reader said about the file, first: a wrong unit or a guessed rate changes
/// everything below it.
fn reader_warnings(out: &mut String, doc: &SkeletonJson) {
    text_list(
        out,
        "What the reader said about the file",
        " class=\"warn\"",
        &doc.reader_warnings,
    );
}

fn notes(out: &mut String, doc: &SkeletonJson) {
    text_list(out, "Notes", "", &doc.notes);
}

/// A heading and a list of escaped lines (`ul_attributes` inside the `<ul>` tag); nothing
/// where there are no lines.
fn text_list(out: &mut String, heading: &str, ul_attributes: &str, lines: &[String]) {
    if lines.is_empty() {
        return;
    }
    let _ = writeln!(out, "<h2>{heading}</h2>\n<ul{ul_attributes}>");
    for line in lines {
        let _ = writeln!(out, "<li>{}</li>", escape(line));
    }
    out.push_str("</ul>\n");
}
