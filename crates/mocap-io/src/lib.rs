//! mocap-io: capture files in, [`Trajectories`] out; and the artifact envelope.
//!
//! Takes C3D (all three processor formats, integer and float), TRC and CSV files (ossify's
//! layout, OptiTrack Motive's and Vicon Nexus's exports) and Qualisys QTM's TSV, and
//! gives [`Trajectories`]: labels, frame rate, first frame, positions in millimetres with
//! gaps as missing samples (one representation, documented on the type), plus a
//! [`CaptureInfo`] saying what the file declared and what was guessed (warnings).
//! [`ReadOptions`] can override the file's units and, in [`read_capture`], keep a range
//! of frames and leave markers out by label; [`read_capture`] also joins the pieces an
//! unlabeled capture cuts one marker into at its gaps (`stitch`).
//! Writes C3D, TRC and CSV for the synthetic generator and the exporters.
//!
//! It also owns the CBOR artifact envelope ([`artifact`]) every stage's output is stored
//! in, the bulk-float encoding ([`bulk`]) and the 4 × 4 eigen-solver of Horn's rigid fit
//! every stage uses ([`eigen4`]). It does not cache, schedule stages or know what a
//! segment is: that is `xtask` and the stage crates.

pub mod artifact;
pub mod bulk;
pub mod c3d;
pub mod csv;
mod disjoint;
pub mod eigen4;
mod error;
mod stitch;
pub mod testdata;
mod trajectories;
pub mod trc;
mod vendor;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use disjoint::DisjointSets;
pub use error::{FormatError, IoError};
pub use trajectories::{
    ABSURD_MM, FLOOR_SPACING_MM, MISSING, SPACING_FRAMES, Trajectories, floor_scale_of, is_present,
};

/// Stage name of capture artifacts.
pub const STAGE: &str = "mocap-io";
/// Schema version of capture artifacts ([`Capture`]).
pub const SCHEMA_VERSION: u32 = 6;

/// The file formats we read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// C3D (c3d.org), any processor type, integer or float.
    C3d,
    /// TRC (Motion Analysis / OpenSim).
    Trc,
    /// ossify's documented CSV layout: `frame,label_x,label_y,label_z,...`.
    Csv,
    /// OptiTrack Motive's CSV export (its `Marker` position columns).
    #[serde(rename = "motive-csv")]
    MotiveCsv,
    /// Vicon Nexus's CSV export (its `Trajectories` section).
    #[serde(rename = "nexus-csv")]
    NexusCsv,
    /// Qualisys Track Manager's TSV export of 3D data.
    #[serde(rename = "qtm-tsv")]
    QtmTsv,
}

impl Format {
    /// Lower-case name as printed by `inspect`.
    pub fn name(self) -> &'static str {
        match self {
            Format::C3d => "c3d",
            Format::Trc => "trc",
            Format::Csv => "csv",
            Format::MotiveCsv => "motive-csv",
            Format::NexusCsv => "nexus-csv",
            Format::QtmTsv => "qtm-tsv",
        }
    }
}

/// What a file declared about itself, beside its trajectories.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CaptureInfo {
    /// Length units as the file declares them ("mm", "cm", "m", "mete", ...); `None` when absent.
    pub declared_units: Option<String>,
    /// C3D only: "intel", "dec" or "mips".
    pub processor: Option<String>,
    /// C3D only: "integer" or "float" (from the sign of POINT:SCALE).
    pub storage: Option<String>,
    /// C3D only: POINT:SCALE as read.
    pub point_scale: Option<f64>,
    /// Things a user should know: guesses made, disagreements resolved, data skipped.
    pub warnings: Vec<String>,
    /// Tracks joined as one marker ([`ReadOptions::stitch`]): per joined marker, the
    /// labels of its pieces in the file, the first being the label it keeps.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stitched: Vec<Vec<String>>,
}

/// A capture as read: its trajectories, format and what the file declared.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Capture {
    /// Format the file was read as.
    pub format: Format,
    /// Marker trajectories in millimetres.
    pub trajectories: Trajectories,
    /// Declarations and warnings.
    pub info: CaptureInfo,
}

/// A length unit of a capture's coordinates ([`ReadOptions::units`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Centimetres.
    Cm,
    /// Metres.
    M,
    /// Inches.
    In,
}

/// Millimetres per unit a file's units word names, in any case, or `None` for a word we
/// do not know: every reader (C3D's POINT:UNITS, TRC's Units, CSV's `# units:`, the
/// vendors' length units) takes the same words. "mete" is "meters" cut to the
/// 4-character field some C3D writers use.
pub(crate) fn mm_per_unit(word: &str) -> Option<f64> {
    match word.trim().to_ascii_lowercase().as_str() {
        "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" => Some(1.0),
        "cm" | "centimeter" | "centimeters" | "centimetre" | "centimetres" => Some(10.0),
        "dm" => Some(100.0),
        "m" | "mete" | "meter" | "meters" | "metre" | "metres" => Some(1000.0),
        "in" | "inch" | "inches" => Some(25.4),
        _ => None,
    }
}

/// The units words [`mm_per_unit`] knows, short, for error messages.
pub(crate) const KNOWN_UNITS: &str = "mm, cm, dm, m or in";

impl LengthUnit {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Mm => 1.0,
            LengthUnit::Cm => 10.0,
            LengthUnit::M => 1000.0,
            LengthUnit::In => 25.4,
        }
    }

    /// The unit as `--set mocap-io.units=` takes it.
    pub fn name(self) -> &'static str {
        match self {
            LengthUnit::Mm => "mm",
            LengthUnit::Cm => "cm",
            LengthUnit::M => "m",
            LengthUnit::In => "in",
        }
    }

    /// The warning for coordinates read in this unit against the file's `declared` one
    /// (millimetres per unit, `None` when the file declares none or one we do not know);
    /// `None` when the two agree.
    pub(crate) fn overriding(self, declared: Option<(&str, Option<f64>)>) -> Option<String> {
        match declared {
            Some((_, Some(mm))) if mm == self.mm() => None,
            Some((text, _)) => Some(format!(
                "coordinates read as {} (mocap-io.units), not as the file's {text:?}",
                self.name()
            )),
            None => Some(format!(
                "coordinates read as {} (mocap-io.units); the file declares no units",
                self.name()
            )),
        }
    }
}

/// Options for reading captures; defaults suit every file we know of.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReadOptions {
    /// C3D: keep samples whose residual is negative when a file flags *every* sample
    /// invalid although its coordinates vary (SIMI writes such files). Default false:
    /// they are read as missing, with a warning naming this option.
    pub keep_invalid_residuals: bool,
    /// C3D: keep the points a file lists as model outputs (POINT:ANGLES, FORCES, MOMENTS,
    /// POWERS, SCALARS, REACTIONS and any group POINT:TYPE_GROUPS names), and the points
    /// no camera saw (residual word 0 in every sample) in a file whose other points
    /// cameras did see. Default false: those are angles, forces, bone-model and virtual
    /// points a program computed, not marker positions, and are dropped with a warning
    /// naming them.
    pub keep_model_outputs: bool,
    /// The unit of the file's coordinates, over what it declares or what is guessed
    /// where it declares none; `None` (default): the file's word, else millimetres
    /// (metres for a C3D whose coordinates are all under 10).
    pub units: Option<LengthUnit>,
    /// The frames to read, first and last inclusive, by the file's own frame numbers
    /// (what `cargo xtask inspect` shows); `None` (default): every frame. A range the
    /// file does not hold is an error, not clipped.
    pub frames: Option<[i64; 2]>,
    /// Markers to leave out, by label (as the capture names them, a repeated label's later
    /// markers `LABEL#2`…; `*` stands for any run of characters, so `V*` is every label
    /// starting with V): a loose marker, a prop or floor marker, virtual points. Default
    /// none; a label or pattern that matches no marker is an error.
    pub exclude_markers: Vec<String>,
    /// Join tracks that are one marker seen in pieces (an unlabeled capture breaks a
    /// marker's trajectory at every occlusion): a piece that ends continues as the piece
    /// that starts where its steady neighbours' rigid motion carries it (see `stitch`).
    /// Default true; a capture with nothing to join reads unchanged.
    pub stitch: bool,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            keep_invalid_residuals: false,
            keep_model_outputs: false,
            units: None,
            frames: None,
            exclude_markers: Vec::new(),
            stitch: true,
        }
    }
}

/// Reads a capture file, choosing the format by content (C3D) or extension (TRC, CSV, TSV),
/// then selects frames and markers and joins pieces as `options` say.
pub fn read_capture(path: &Path, options: &ReadOptions) -> Result<Capture, IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    let format = detect_format(path, &bytes).ok_or_else(|| IoError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let parsed = match format {
        Format::C3d => c3d::parse(&bytes, options),
        Format::Trc => trc::parse(&bytes, options),
        Format::Csv => csv::parse(&bytes, options),
        Format::MotiveCsv => vendor::motive::parse(&bytes, options),
        Format::NexusCsv => vendor::nexus::parse(&bytes, options),
        Format::QtmTsv => vendor::qtm::parse(&bytes, options),
    };
    parsed
        .and_then(|capture| select(capture, options))
        .map(|capture| {
            if options.stitch {
                stitch(capture)
            } else {
                capture
            }
        })
        .map(|mut capture| {
            let warning = implausible_spacing(&capture, options);
            capture.info.warnings.extend(warning);
            capture
        })
        .map_err(|error| IoError::Format {
            path: path.to_path_buf(),
            error,
        })
}

/// Median nearest-marker distances (mm) outside which no marker set lies: a marker is a
/// sphere of a few millimetres (the smallest in use, 3 mm, touch at 3 mm), and a body
/// carries its markers centimetres apart (the shared real captures 20-321 mm, the
/// generator's subjects 28-94 mm), a vehicle or a crane a few metres at most. Millimetres
/// read as metres put a body's markers 20 m apart and more, metres read as millimetres
/// under 0.5 mm.
pub const PLAUSIBLE_SPACING_MM: [f64; 2] = [2.0, 10_000.0];

/// The warning for a capture whose markers, in the unit its coordinates were read in, lie
/// implausibly close or far apart ([`PLAUSIBLE_SPACING_MM`]): a units line that does not
/// match the numbers (a TRC saying `m` over millimetres) turns a body into a stadium, and
/// every stage's millimetre tolerances with it. Names the unit that would put the markers
/// nearest [`FLOOR_SPACING_MM`] apart where one does; `None` where the spacing is
/// plausible.
fn implausible_spacing(capture: &Capture, options: &ReadOptions) -> Option<String> {
    let spacing = capture.trajectories.marker_spacing_mm()?;
    let [low, high] = PLAUSIBLE_SPACING_MM;
    if (low..=high).contains(&spacing) {
        return None;
    }
    // The unit the reader applied: the option, else the file's word, else the format's
    // assumption (Motive's metres, everyone else's millimetres).
    let assumed = match capture.format {
        Format::MotiveCsv => vendor::motive::ASSUMED_UNIT.0,
        _ => 1.0,
    };
    let applied = options.units.map(LengthUnit::mm).unwrap_or_else(|| {
        let declared = capture.info.declared_units.as_deref();
        declared.and_then(mm_per_unit).unwrap_or(assumed)
    });
    let typical = FLOOR_SPACING_MM;
    let suggestion = [
        LengthUnit::Mm,
        LengthUnit::Cm,
        LengthUnit::M,
        LengthUnit::In,
    ]
    .into_iter()
    .map(|u| (u, spacing * u.mm() / applied))
    .filter(|&(_, s)| (low..=high).contains(&s))
    .min_by(|a, b| {
        (a.1 / typical)
            .ln()
            .abs()
            .total_cmp(&(b.1 / typical).ln().abs())
    });
    let side = if spacing < low {
        "closer together"
    } else {
        "farther apart"
    };
    let advice = match suggestion {
        Some((u, s)) => format!(
            "if the coordinates are in {name}, --set mocap-io.units={name} reads them so \
             ({s:.1} mm apart)",
            name = u.name()
        ),
        None => "check the file's units".to_string(),
    };
    Some(format!(
        "markers lie a median {spacing:.3} mm from their nearest neighbour as read, {side} \
         than in any marker set ({low} to {high} mm): the units look wrong; {advice}"
    ))
}

/// The capture with the pieces of each marker joined, as [`read_capture`] does when
/// [`ReadOptions::stitch`] is on (for captures built in memory).
pub fn stitch(capture: Capture) -> Capture {
    stitch::join_pieces(capture)
}

/// A capture as read, cut to `options.frames` and without `options.exclude_markers`.
fn select(mut capture: Capture, options: &ReadOptions) -> Result<Capture, FormatError> {
    if options.frames.is_none() && options.exclude_markers.is_empty() {
        return Ok(capture);
    }
    let t = &capture.trajectories;
    let last = t.first_frame().saturating_add(t.frames() as i64 - 1);
    let held = || {
        if t.frames() == 0 {
            "it holds no frames".to_string()
        } else {
            format!("it holds frames {} to {last}", t.first_frame())
        }
    };
    let frames = match options.frames {
        None => 0..t.frames(),
        Some([from, to]) if from > to => {
            return Err(FormatError::new(
                "mocap-io.frames",
                format!("the first frame {from} comes after the last, {to}"),
            ));
        }
        Some([from, to]) if from < t.first_frame() || to > last => {
            return Err(FormatError::new(
                "mocap-io.frames",
                format!(
                    "frames {from} to {to} are not all in the capture: {}",
                    held()
                ),
            ));
        }
        Some([from, to]) => {
            let start = (from - t.first_frame()) as usize;
            start..start + (to - from) as usize + 1
        }
    };
    let labels = t.labels();
    let mut excluded = vec![false; labels.len()];
    for pattern in &options.exclude_markers {
        let named = markers_named(labels, pattern);
        if named.is_empty() {
            return Err(FormatError::new(
                "mocap-io.exclude_markers",
                no_marker_named(labels, pattern),
            ));
        }
        for m in named {
            excluded[m] = true;
        }
    }
    let keep: Vec<usize> = (0..labels.len()).filter(|&m| !excluded[m]).collect();
    if keep.is_empty() {
        return Err(FormatError::new(
            "mocap-io.exclude_markers",
            "it leaves out every marker of the capture",
        ));
    }
    let mut notes = Vec::new();
    if options.frames.is_some() {
        let from = t.first_frame() + frames.start as i64;
        notes.push(format!(
            "read frames {from} to {} of {} to {last} (mocap-io.frames)",
            from + frames.len() as i64 - 1,
            t.first_frame()
        ));
    }
    if !options.exclude_markers.is_empty() {
        notes.push(format!(
            "left out {} of {} markers (mocap-io.exclude_markers): {}",
            labels.len() - keep.len(),
            labels.len(),
            (0..labels.len())
                .filter(|&m| excluded[m])
                .map(|m| labels[m].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    capture.trajectories = t.select(frames, &keep);
    capture.info.warnings.extend(notes);
    Ok(capture)
}

/// The markers whose label `pattern` names, in capture order: the label itself, or with
/// `*` standing for any run of characters (`V*`: every label starting with V).
pub fn markers_named(labels: &[String], pattern: &str) -> Vec<usize> {
    (0..labels.len())
        .filter(|&m| glob(pattern, &labels[m]))
        .collect()
}

/// Why `pattern` names no marker of `labels`, for an error message: with the label it
/// may mean (another case, or Vicon's "Subject:LABEL"), else the capture's first labels.
pub fn no_marker_named(labels: &[String], pattern: &str) -> String {
    let like = labels.iter().find(|l| {
        l.eq_ignore_ascii_case(pattern)
            || l.rsplit_once(':')
                .is_some_and(|(_, bare)| bare.eq_ignore_ascii_case(pattern))
    });
    let hint = match like {
        Some(label) => format!("; did you mean {label:?}?"),
        None => {
            let shown = labels
                .iter()
                .take(12)
                .map(String::as_str)
                .collect::<Vec<_>>();
            let more = if labels.len() > shown.len() {
                ", …"
            } else {
                ""
            };
            format!(
                " (its {} markers: {}{more})",
                labels.len(),
                shown.join(", ")
            )
        }
    };
    let what = if pattern.contains('*') {
        format!("no marker of the capture matches {pattern:?}")
    } else {
        format!("the capture has no marker labelled {pattern:?}")
    };
    format!("{what}{hint}")
}

/// Whether `label` matches `pattern`, where `*` stands for any run of characters
/// (none included) and everything else for itself.
fn glob(pattern: &str, label: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = label.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for part in middle {
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

/// The format of a file: by extension (a `.csv` by its first line: Motive's, Nexus's or
/// ossify's layout), else by its first bytes (C3D's 0x50 key, TRC's `PathFileType`, QTM's
/// `NO_OF_FRAMES`).
pub fn detect_format(path: &Path, bytes: &[u8]) -> Option<Format> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("c3d") => Some(Format::C3d),
        Some("trc") => Some(Format::Trc),
        Some("csv") => Some(vendor::sniff_csv(bytes).unwrap_or(Format::Csv)),
        Some("tsv") => Some(Format::QtmTsv),
        _ if bytes.len() >= 2 && bytes[1] == 0x50 => Some(Format::C3d),
        _ if bytes.starts_with(b"PathFileType") => Some(Format::Trc),
        _ if vendor::qtm::sniff(bytes) => Some(Format::QtmTsv),
        _ => None,
    }
}

/// Writes trajectories as a C3D file (Intel, float, residual −1 for missing samples), atomically.
pub fn write_c3d(path: &Path, trajectories: &Trajectories) -> Result<(), IoError> {
    artifact::write_atomic(path, &c3d::write(trajectories)?)
}

/// Writes trajectories as a TRC file (millimetres, empty fields for missing samples), atomically.
pub fn write_trc(path: &Path, trajectories: &Trajectories) -> Result<(), IoError> {
    artifact::write_atomic(path, trc::write(trajectories).as_bytes())
}

/// Writes trajectories in ossify's CSV layout, atomically.
pub fn write_csv(path: &Path, trajectories: &Trajectories) -> Result<(), IoError> {
    artifact::write_atomic(path, csv::write(trajectories).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::{glob, mm_per_unit};

    #[test]
    fn units_words_convert_to_millimetres() {
        assert_eq!(mm_per_unit("mete"), Some(1000.0));
        assert_eq!(mm_per_unit(" cm "), Some(10.0));
        assert_eq!(mm_per_unit("MM"), Some(1.0));
        assert_eq!(mm_per_unit("Inches"), Some(25.4));
        assert_eq!(mm_per_unit("furlong"), None);
    }

    #[test]
    fn a_star_stands_for_any_run_of_characters() {
        for (pattern, label) in [
            ("V*", "VMID#2"),
            ("*", ""),
            ("*TOE", "Subject:LTOE"),
            ("L*#*", "LKNE#2"),
            ("a*b*c", "abbc"),
            ("LTOE", "LTOE"),
        ] {
            assert!(glob(pattern, label), "{pattern} {label}");
        }
        for (pattern, label) in [
            ("V*", "RVAN"),
            ("LTOE", "LTOE#2"),
            ("a*a", "a"),
            ("a*b*c", "acb"),
            ("*TOE", "LTOE2"),
        ] {
            assert!(!glob(pattern, label), "{pattern} {label}");
        }
    }
}
