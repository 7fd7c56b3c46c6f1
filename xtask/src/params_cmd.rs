//! `cargo xtask params`: every stage parameter with its default and meaning.

use anyhow::Result;
use serde_json::{Value as Json, json};

use crate::pipeline::{Params, StageId};

/// Arguments of `params`.
#[derive(clap::Args)]
pub struct Args {
    /// Print a JSON array of {name, default, meaning} instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Show the values after these assignments instead of the defaults. Repeatable.
    #[arg(long = "set", value_name = "STAGE.PARAM=VALUE")]
    pub set: Vec<String>,
}

/// One parameter: `stage.field`, its value, its documentation.
pub struct Row {
    /// `stage.field`.
    pub name: String,
    /// Default (or assigned) value, as JSON.
    pub value: Json,
    /// Meaning, units, default (the stage's `PARAM_DOCS`); empty when undocumented.
    pub meaning: String,
}

/// Every parameter of every stage, in pipeline order and each stage's field order.
pub fn rows(params: &Params) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    for stage in StageId::ALL {
        let docs = stage.param_docs();
        let value = params.json(stage)?;
        let mut fields: Vec<(String, Json)> = match value {
            Json::Object(map) => map.into_iter().collect(),
            _ => Vec::new(),
        };
        // Documentation order first (the author's order), then anything undocumented.
        fields.sort_by_key(|(name, _)| {
            docs.iter()
                .position(|(n, _)| n == name)
                .unwrap_or(usize::MAX)
        });
        for (field, value) in fields {
            let meaning = docs
                .iter()
                .find(|(n, _)| *n == field)
                .map_or(String::new(), |(_, m)| (*m).to_string());
            rows.push(Row {
                name: format!("{}.{field}", stage.name()),
                value,
                meaning,
            });
        }
        // Documented fields the stage skips when serializing (an absent Option) still exist.
        for (field, meaning) in docs {
            let name = format!("{}.{field}", stage.name());
            if !rows.iter().any(|r| r.name == name) {
                rows.push(Row {
                    name,
                    value: Json::Null,
                    meaning: (*meaning).to_string(),
                });
            }
        }
    }
    Ok(rows)
}

/// Runs `params`.
pub fn main(args: &Args) -> Result<()> {
    let params = Params::from_assignments(&args.set)?;
    let rows = rows(&params)?;
    if args.json {
        let list: Vec<Json> = rows
            .iter()
            .map(|r| json!({"name": r.name, "default": r.value, "meaning": r.meaning}))
            .collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    let width = rows.iter().map(|r| r.name.len()).max().unwrap_or(0);
    let vwidth = rows
        .iter()
        .map(|r| r.value.to_string().len())
        .max()
        .unwrap_or(0)
        .min(24);
    let mut last_stage = "";
    for r in &rows {
        let stage = r.name.split('.').next().unwrap_or("");
        if stage != last_stage {
            if !last_stage.is_empty() {
                println!();
            }
            println!("[{stage}]");
            last_stage = stage;
        }
        let meaning = if r.meaning.is_empty() {
            "(undocumented)"
        } else {
            &r.meaning
        };
        println!(
            "  {:<width$}  {:<vwidth$}  {meaning}",
            r.name,
            r.value.to_string()
        );
    }
    println!(
        "\nSet with: cargo xtask run --set STAGE.PARAM=VALUE (VALUE is JSON, or a plain string)"
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stage_field_is_listed_and_documented() {
        let rows = rows(&Params::default()).unwrap();
        for stage in StageId::ALL {
            for (field, _) in stage.param_docs() {
                let name = format!("{}.{field}", stage.name());
                assert!(rows.iter().any(|r| r.name == name), "{name} missing");
            }
        }
        let undocumented: Vec<_> = rows
            .iter()
            .filter(|r| r.meaning.is_empty())
            .map(|r| &r.name)
            .collect();
        assert!(undocumented.is_empty(), "undocumented: {undocumented:?}");
        let alpha = rows.iter().find(|r| r.name == "jointfit.alpha").unwrap();
        assert_eq!(alpha.value, json!(0.2));
    }
}
