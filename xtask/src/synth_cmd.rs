//! `cargo xtask synth`: a synthetic trial with ground truth, written to a folder.

use std::path::PathBuf;

use anyhow::{Context as _, Result};
use synth::{Preset, Subject, SynthConfig};

/// Arguments of `synth`.
#[derive(clap::Args)]
pub struct Args {
    /// Subject: human, quadruped, robotarm, snowman, hexapod, random, snake.
    #[arg(long, default_value = "human")]
    pub subject: String,
    /// Degradation: clean, noise, skin, gaps, swap, hard (noise + skin + gaps), messy (hard + swap).
    #[arg(long, default_value = "clean")]
    pub preset: String,
    /// Number of frames [default: the generator's, 240].
    #[arg(long)]
    pub frames: Option<usize>,
    /// Seed of every random choice [default: 1].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Frame rate in Hz [default: 120].
    #[arg(long)]
    pub rate: Option<f64>,
    /// Gaussian noise σ per coordinate in mm, for the noise and hard presets [default: 1].
    #[arg(long = "noise", value_name = "MM")]
    pub noise_mm: Option<f64>,
    /// Markers per segment as MIN:MAX (or one number) [default: 3:6].
    #[arg(long, value_name = "MIN:MAX")]
    pub markers: Option<String>,
    /// Share of each joint's range swept, as MIN:MAX (or one share), each in (0, 1]
    /// [default: 0.7:0.95; a walk is nearer 0.2:0.4].
    #[arg(long, value_name = "MIN:MAX")]
    pub sweep: Option<String>,
    /// Arc of directions around each bone the markers sit in, degrees, one side per segment
    /// [default: 360 = all round; real limb sets nearer 90–120].
    #[arg(long, value_name = "DEG")]
    pub marker_arc: Option<f64>,
    /// Each marker's soft-tissue artefact amplitude, mm, as MIN:MAX (or one value), for the
    /// skin, hard and messy presets [default: 5:15; real walks move about half that].
    #[arg(long, value_name = "MIN:MAX")]
    pub skin: Option<String>,
    /// Also write a TRC file.
    #[arg(long)]
    pub trc: bool,
    /// Output folder: <name>.c3d, <name>.truth.json (and <name>.trc).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
}

/// The generator's config from the arguments.
pub fn config(args: &Args) -> Result<SynthConfig> {
    let defaults = SynthConfig::default();
    let subject: Subject = args.subject.parse()?;
    let preset: Preset = args.preset.parse()?;
    let markers_per_segment = markers_arg(args.markers.as_deref())?;
    let sweep = sweep_arg(args.sweep.as_deref())?;
    let skin_mm = skin_arg(args.skin.as_deref())?;
    let config = SynthConfig {
        subject,
        preset,
        frames: args.frames.unwrap_or(defaults.frames),
        rate: args.rate.unwrap_or(defaults.rate),
        seed: args.seed.unwrap_or(defaults.seed),
        noise_mm: args.noise_mm.unwrap_or(defaults.noise_mm),
        markers_per_segment,
        sweep,
        marker_arc_deg: args.marker_arc.unwrap_or(defaults.marker_arc_deg),
        skin_mm,
    };
    config.validate()?;
    Ok(config)
}

/// `--markers` as given (see [`parse_range`]), else the generator's default.
pub fn markers_arg(text: Option<&str>) -> Result<(usize, usize)> {
    text.map_or(Ok(SynthConfig::default().markers_per_segment), |text| {
        parse_range(text).with_context(|| format!("--markers {text}: expected MIN:MAX or N"))
    })
}

/// `--sweep` as given (see [`parse_share_range`]), else the generator's default.
pub fn sweep_arg(text: Option<&str>) -> Result<(f64, f64)> {
    text.map_or(Ok(SynthConfig::default().sweep), parse_share_range)
}

/// `--skin` as given (`MIN:MAX`, `MIN,MAX` or one value, mm), else the generator's default.
pub fn skin_arg(text: Option<&str>) -> Result<(f64, f64)> {
    text.map_or(Ok(SynthConfig::default().skin_mm), |text| {
        parse_f64_range(text, "--skin")
    })
}

/// `MIN:MAX` (or `MIN-MAX`, `MIN,MAX`, one number) as a range of markers per segment.
pub fn parse_range(text: &str) -> Result<(usize, usize)> {
    let (lo, hi) = text.split_once([':', '-', ',']).unwrap_or((text, text));
    Ok((lo.trim().parse()?, hi.trim().parse()?))
}

/// `MIN:MAX` (or `MIN,MAX`, one number) as a range of shares of a joint's range.
pub fn parse_share_range(text: &str) -> Result<(f64, f64)> {
    parse_f64_range(text, "--sweep")
}

/// `MIN:MAX` (or `MIN,MAX`, one number) as a range of numbers, for the option `flag`.
fn parse_f64_range(text: &str, flag: &str) -> Result<(f64, f64)> {
    let (lo, hi) = text.split_once([':', ',']).unwrap_or((text, text));
    let number = |s: &str| {
        s.trim()
            .parse::<f64>()
            .with_context(|| format!("{flag} {text}: {s:?} is not a number"))
    };
    Ok((number(lo)?, number(hi)?))
}

/// Runs `synth`.
pub fn main(args: &Args) -> Result<()> {
    let config = config(args)?;
    let trial =
        synth::generate(&config).with_context(|| format!("generating {}", config.trial_name()))?;
    let written = synth::write_trial(&args.out, &trial, args.trc)
        .with_context(|| format!("writing {} into {}", trial.name, args.out.display()))?;
    let t = &trial.trajectories;
    eprintln!(
        "{}: {} segments, {} joints, {} markers, {} frames at {} Hz, {} missing samples",
        trial.name,
        trial.truth.segments.len(),
        trial.truth.joints.len(),
        t.markers(),
        t.frames(),
        t.frame_rate(),
        t.missing_samples()
    );
    for path in written {
        println!("{}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse() {
        assert_eq!(parse_range("3:6").unwrap(), (3, 6));
        assert_eq!(parse_range("2").unwrap(), (2, 2));
        assert_eq!(parse_range("1-4").unwrap(), (1, 4));
        assert!(parse_range("a:b").is_err());
        assert_eq!(parse_share_range("0.2:0.4").unwrap(), (0.2, 0.4));
        assert_eq!(parse_share_range("0.3").unwrap(), (0.3, 0.3));
        assert!(parse_share_range("0.2:x").is_err());
    }
}
