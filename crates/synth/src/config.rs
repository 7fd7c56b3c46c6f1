//! What to generate: subject, degradation preset, length, rate, seed, noise, marker counts
//! and placement, how much of its range each joint sweeps.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::Error;

/// One synthetic trial's recipe; [`crate::generate`] turns it into a [`crate::Trial`].
///
/// The same config gives byte-identical output. The subject's body, markers and motion
/// depend only on `subject`, `seed`, `frames`, `rate` and `markers_per_segment`, not on
/// `preset`: `human-clean-s1` and `human-hard-s1` show the same body doing the same
/// motion, one clean and one degraded.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthConfig {
    /// The articulated subject. Default human.
    pub subject: Subject,
    /// The degradation applied to the clean markers. Default clean.
    pub preset: Preset,
    /// Number of frames (≥ 2). Default 240.
    pub frames: usize,
    /// Frame rate in Hz (> 0). Default 120.
    pub rate: f64,
    /// Seed of every random choice (body proportions, markers, motion, degradation). Default 1.
    pub seed: u64,
    /// Standard deviation of the Gaussian noise per coordinate in mm, for the `noise` and
    /// `hard` presets (≥ 0). Default 1.
    pub noise_mm: f64,
    /// Inclusive range of the number of markers per segment (1 ≤ min ≤ max). Default (3, 6).
    pub markers_per_segment: (usize, usize),
    /// Range of the share of each joint's range a trial sweeps (0 < min ≤ max ≤ 1): every
    /// degree of freedom draws its share in it. Default (0.7, 0.95); a walk moves most
    /// joints through far less, (0.2, 0.4) or so.
    pub sweep: (f64, f64),
    /// Arc of directions around each segment's bone its markers sit in, degrees
    /// (0 < arc ≤ 360), centred on a random side per segment. Default 360 (all round); real
    /// limb marker sets sit on one side (CMU's thigh, knee, shin and ankle markers are all
    /// lateral), nearer 90–120.
    pub marker_arc_deg: f64,
    /// Range of each marker's soft-tissue artefact amplitude (its largest displacement over
    /// the trial), mm, drawn per marker, for the `skin`, `hard` and `messy` presets
    /// (0 ≤ min ≤ max). Default (5, 15), whatever the range of motion; real walks' soft
    /// tissue moves about half as much (see the README).
    pub skin_mm: (f64, f64),
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            subject: Subject::Human,
            preset: Preset::Clean,
            frames: 240,
            rate: 120.0,
            seed: 1,
            noise_mm: 1.0,
            markers_per_segment: (3, 6),
            sweep: (0.7, 0.95),
            marker_arc_deg: 360.0,
            skin_mm: (5.0, 15.0),
        }
    }
}

/// (field, "meaning, units, default") for every [`SynthConfig`] field, for CLIs to print.
pub const CONFIG_DOCS: &[(&str, &str)] = &[
    (
        "subject",
        "articulated subject: human, quadruped, robotarm, snowman, hexapod, random, snake; \
         default human",
    ),
    (
        "preset",
        "degradation: clean, noise, skin, gaps, swap, hard (noise + skin + gaps), messy (hard + swap); default clean",
    ),
    ("frames", "number of frames (>= 2); default 240"),
    ("rate", "frame rate in Hz (> 0); default 120"),
    ("seed", "seed of every random choice; default 1"),
    (
        "noise_mm",
        "Gaussian noise sigma per coordinate in mm (noise and hard presets); default 1",
    ),
    (
        "markers_per_segment",
        "inclusive [min, max] markers per segment (min >= 1); default [3, 6]",
    ),
    (
        "sweep",
        "[min, max] share of each joint's range swept over the trial, drawn per degree of freedom (0 < min <= max <= 1); default [0.7, 0.95]",
    ),
    (
        "marker_arc_deg",
        "arc of directions around each segment's bone its markers sit in, degrees, centred on a random side per segment (0 < arc <= 360); default 360 (all round; one-sided real limb sets nearer 90-120)",
    ),
    (
        "skin_mm",
        "[min, max] of each marker's soft-tissue artefact amplitude (largest displacement over the trial) in mm, drawn per marker (skin, hard and messy presets; 0 <= min <= max); default [5, 15], whatever the range of motion",
    ),
];

impl SynthConfig {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |field, problem: String| Err(Error::InvalidConfig { field, problem });
        if self.frames < 2 {
            return bad("frames", format!("is {}, must be at least 2", self.frames));
        }
        if !(self.rate.is_finite() && self.rate > 0.0) {
            return bad(
                "rate",
                format!("is {} Hz, must be a positive number", self.rate),
            );
        }
        if !(self.noise_mm.is_finite() && self.noise_mm >= 0.0) {
            return bad(
                "noise_mm",
                format!("is {} mm, must be a non-negative number", self.noise_mm),
            );
        }
        let (lo, hi) = self.markers_per_segment;
        if lo == 0 || lo > hi || hi > 64 {
            return bad(
                "markers_per_segment",
                format!("is ({lo}, {hi}), must satisfy 1 <= min <= max <= 64"),
            );
        }
        let (lo, hi) = self.sweep;
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi && hi <= 1.0) {
            return bad(
                "sweep",
                format!("is ({lo}, {hi}), must satisfy 0 < min <= max <= 1"),
            );
        }
        let arc = self.marker_arc_deg;
        if !(arc.is_finite() && 0.0 < arc && arc <= 360.0) {
            return bad(
                "marker_arc_deg",
                format!("is {arc}, must satisfy 0 < arc <= 360"),
            );
        }
        let (lo, hi) = self.skin_mm;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi) {
            return bad(
                "skin_mm",
                format!("is ({lo}, {hi}) mm, must satisfy 0 <= min <= max"),
            );
        }
        Ok(())
    }

    /// The trial's name, `<subject>-<preset>-s<seed>`, e.g. `human-clean-s1`.
    pub fn trial_name(&self) -> String {
        format!(
            "{}-{}-s{}",
            self.subject.name(),
            self.preset.name(),
            self.seed
        )
    }
}

/// The articulated subjects the generator knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Subject {
    /// 18 segments: pelvis, abdomen, thorax, head, clavicles, arms, forearms, hands,
    /// thighs, shanks, feet; ball spine, neck, shoulders, hips, wrists; hinge elbows,
    /// knees, ankles. Standing height 1750 mm ± 10 %.
    Human,
    /// 18 segments: hindquarters, chest, neck, head, a two-segment tail, four three-segment legs.
    Quadruped,
    /// A mobile base and six links joined by hinges whose axes are perpendicular to the links.
    Robotarm,
    /// The paper's jumping snowman: three balls, two-segment stick arms; 7 segments.
    Snowman,
    /// A body and six legs of two (ball hip, hinge knee) or three (three hinges) segments.
    Hexapod,
    /// A random tree of 5–15 segments, bones 50–600 mm, ball and hinge joints.
    Random,
    /// A mobile base and 5–7 links in a chain joined by universal joints (two axes across
    /// each link), like a modular snake robot standing up.
    Snake,
}

impl Subject {
    /// Every subject, in documentation order.
    pub const ALL: [Subject; 7] = [
        Subject::Human,
        Subject::Quadruped,
        Subject::Robotarm,
        Subject::Snowman,
        Subject::Hexapod,
        Subject::Random,
        Subject::Snake,
    ];

    /// Lower-case name, as on the command line and in trial names.
    pub fn name(self) -> &'static str {
        match self {
            Subject::Human => "human",
            Subject::Quadruped => "quadruped",
            Subject::Robotarm => "robotarm",
            Subject::Snowman => "snowman",
            Subject::Hexapod => "hexapod",
            Subject::Random => "random",
            Subject::Snake => "snake",
        }
    }
}

impl FromStr for Subject {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        Subject::ALL
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| Error::UnknownName {
                kind: "subject",
                name: s.to_string(),
                expected: Subject::ALL.map(Subject::name).join(", "),
            })
    }
}

impl fmt::Display for Subject {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Degradations applied to the clean marker trajectories.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Markers exactly rigid in their segment; nothing missing.
    Clean,
    /// Independent Gaussian noise, σ = `noise_mm` per coordinate.
    Noise,
    /// Soft-tissue artefact: every marker slides 5–15 mm on its segment, driven smoothly
    /// by the angles of the segment's joints, half of it shared by the segment's markers.
    Skin,
    /// Holes: 2–20-frame holes in about half the markers, one 10–30 %-of-trial hole in a
    /// few (markers / 15, at least 1), and one marker lost for the second half.
    Gaps,
    /// Two nearby markers of different segments exchange labels for 15 % of the trial.
    Swap,
    /// noise + skin + gaps.
    Hard,
    /// hard + swap: everything a real capture does at once.
    Messy,
}

impl Preset {
    /// Every preset, in documentation order.
    pub const ALL: [Preset; 7] = [
        Preset::Clean,
        Preset::Noise,
        Preset::Skin,
        Preset::Gaps,
        Preset::Swap,
        Preset::Hard,
        Preset::Messy,
    ];

    /// Lower-case name, as on the command line and in trial names.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Clean => "clean",
            Preset::Noise => "noise",
            Preset::Skin => "skin",
            Preset::Gaps => "gaps",
            Preset::Swap => "swap",
            Preset::Hard => "hard",
            Preset::Messy => "messy",
        }
    }

    /// True when this preset adds Gaussian noise.
    pub fn has_noise(self) -> bool {
        matches!(self, Preset::Noise | Preset::Hard | Preset::Messy)
    }
    /// True when this preset adds soft-tissue artefact.
    pub fn has_skin(self) -> bool {
        matches!(self, Preset::Skin | Preset::Hard | Preset::Messy)
    }
    /// True when this preset punches holes.
    pub fn has_gaps(self) -> bool {
        matches!(self, Preset::Gaps | Preset::Hard | Preset::Messy)
    }
    /// True when this preset swaps two labels.
    pub fn has_swap(self) -> bool {
        matches!(self, Preset::Swap | Preset::Messy)
    }
}

impl FromStr for Preset {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self, Error> {
        Preset::ALL
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| Error::UnknownName {
                kind: "preset",
                name: s.to_string(),
                expected: Preset::ALL.map(Preset::name).join(", "),
            })
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_valid_ones() {
        for s in Subject::ALL {
            assert_eq!(s.name().parse::<Subject>().ok(), Some(s));
        }
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>().ok(), Some(p));
        }
        let err = "robot".parse::<Subject>().err().map(|e| e.to_string());
        assert!(err.is_some_and(|e| e.contains("robotarm")));
    }

    #[test]
    fn config_serde_and_validation() {
        let c = SynthConfig::default();
        let json = serde_json::to_string(&c).unwrap();
        assert!(json.contains("\"subject\":\"human\""));
        let back: SynthConfig = serde_json::from_str(&json).unwrap();
        assert_eq!(back, c);
        assert_eq!(c.trial_name(), "human-clean-s1");
        let bad = SynthConfig {
            markers_per_segment: (0, 3),
            ..c.clone()
        };
        assert!(bad.validate().is_err());
        let bad = SynthConfig { frames: 1, ..c };
        assert!(bad.validate().is_err());
    }
}
