//! `--set STAGE.PARAM=VALUE`: parsing an assignment and applying it to a stage's `Params`.
//!
//! VALUE is read as JSON when it parses (`0.25`, `true`, `"text"`, `[1, 2]`, `null`),
//! else taken as a plain string (`aguiar`), so enum variants need no quotes. The field is
//! set on the stage's parameters serialized to a JSON object, which is then deserialized
//! back: unknown fields and wrong types are reported by the stage's own serde rules
//! (`deny_unknown_fields`), in words naming the assignment.

use anyhow::{Result, anyhow, bail};
use serde::{Serialize, de::DeserializeOwned};
use serde_json::Value as Json;

/// One parsed `STAGE.PARAM=VALUE`.
#[derive(Clone, Debug, PartialEq)]
pub struct Assignment {
    /// Stage name as written ("jointfit").
    pub stage: String,
    /// Field path inside the stage's params (usually one field; nested with more dots).
    pub path: Vec<String>,
    /// The value.
    pub value: Json,
    /// The assignment as given, for messages.
    pub text: String,
}

/// Parses `STAGE.PARAM=VALUE`.
pub fn parse_assignment(text: &str) -> Result<Assignment> {
    let (lhs, rhs) = text
        .split_once('=')
        .ok_or_else(|| anyhow!("--set {text}: expected STAGE.PARAM=VALUE"))?;
    let (stage, field) = lhs
        .trim()
        .split_once('.')
        .ok_or_else(|| anyhow!("--set {text}: expected STAGE.PARAM=VALUE (no '.' before '=')"))?;
    let path: Vec<String> = field.split('.').map(|s| s.trim().to_string()).collect();
    if stage.trim().is_empty() || path.iter().any(|p| p.is_empty()) {
        bail!("--set {text}: empty stage or parameter name");
    }
    Ok(Assignment {
        stage: stage.trim().to_string(),
        path,
        value: parse_value(rhs),
        text: text.to_string(),
    })
}

/// VALUE as JSON when it parses, else as a string.
pub fn parse_value(text: &str) -> Json {
    serde_json::from_str(text.trim()).unwrap_or_else(|_| Json::String(text.to_string()))
}

/// Returns `current` with the assignment applied.
///
/// `docs` is the stage's `PARAM_DOCS`, used with the serialized fields to list the valid
/// names when the field is unknown.
pub fn apply<P: Serialize + DeserializeOwned>(
    current: &P,
    assignment: &Assignment,
    docs: &[(&str, &str)],
) -> Result<P> {
    let stage = &assignment.stage;
    let mut root = serde_json::to_value(current)
        .map_err(|e| anyhow!("{stage}: cannot represent the parameters as JSON: {e}"))?;
    let valid = |obj: &serde_json::Map<String, Json>| {
        let mut names: Vec<String> = obj.keys().cloned().collect();
        for (name, _) in docs {
            if !names.iter().any(|n| n == name) {
                names.push((*name).to_string());
            }
        }
        names.sort();
        names.join(", ")
    };
    let (last, parents) = assignment
        .path
        .split_last()
        .ok_or_else(|| anyhow!("--set {}: no parameter name", assignment.text))?;
    let mut node = &mut root;
    let mut walked = stage.clone();
    for part in parents {
        let obj = node
            .as_object_mut()
            .ok_or_else(|| anyhow!("--set {}: {walked} has no fields", assignment.text))?;
        let names = valid(obj);
        node = obj.get_mut(part).ok_or_else(|| {
            anyhow!(
                "--set {}: {walked} has no parameter '{part}'; valid: {names}",
                assignment.text
            )
        })?;
        walked = format!("{walked}.{part}");
    }
    let top_level = parents.is_empty();
    let obj = node
        .as_object_mut()
        .ok_or_else(|| anyhow!("--set {}: {walked} has no fields", assignment.text))?;
    // A field the stage skips when serializing (e.g. an absent Option) is still valid if
    // the docs name it; deserialization below is the final judge.
    let known = obj.contains_key(last) || (top_level && docs.iter().any(|(n, _)| n == last));
    if !known {
        bail!(
            "--set {}: {walked} has no parameter '{last}'; valid: {}",
            assignment.text,
            valid(obj)
        );
    }
    obj.insert(last.clone(), assignment.value.clone());
    serde_json::from_value(root).map_err(|e| {
        anyhow!(
            "--set {}: not a valid value for {walked}.{last}: {e}",
            assignment.text
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(rename_all = "lowercase")]
    enum Method {
        Aguiar,
        Score,
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(default, deny_unknown_fields)]
    struct P {
        alpha: f64,
        restarts: usize,
        method: Method,
        robust: bool,
        label: Option<String>,
    }

    impl Default for P {
        fn default() -> Self {
            Self {
                alpha: 0.2,
                restarts: 10,
                method: Method::Aguiar,
                robust: false,
                label: None,
            }
        }
    }

    const DOCS: &[(&str, &str)] = &[("alpha", "a"), ("restarts", "r")];

    fn set(p: &P, text: &str) -> Result<P> {
        apply(p, &parse_assignment(text)?, DOCS)
    }

    #[test]
    fn values_parse_as_json_else_string() {
        assert_eq!(parse_value("0.25"), serde_json::json!(0.25));
        assert_eq!(parse_value("true"), serde_json::json!(true));
        assert_eq!(parse_value("\"x y\""), serde_json::json!("x y"));
        assert_eq!(parse_value("aguiar"), serde_json::json!("aguiar"));
        assert_eq!(parse_value("null"), Json::Null);
        let a = parse_assignment("jointfit.alpha=0.25").unwrap();
        assert_eq!(a.stage, "jointfit");
        assert_eq!(a.path, vec!["alpha"]);
        assert_eq!(a.value, serde_json::json!(0.25));
        // '=' inside the value stays in the value.
        let a = parse_assignment("export.title=a=b").unwrap();
        assert_eq!(a.value, serde_json::json!("a=b"));
        assert!(parse_assignment("jointfit.alpha").is_err());
        assert!(parse_assignment("alpha=1").is_err());
        assert!(parse_assignment(".alpha=1").is_err());
    }

    #[test]
    fn applies_fields_of_every_type() {
        let p = P::default();
        assert_eq!(set(&p, "jointfit.alpha=0.25").unwrap().alpha, 0.25);
        // An integer is a fine f64.
        assert_eq!(set(&p, "jointfit.alpha=1").unwrap().alpha, 1.0);
        assert_eq!(set(&p, "jointfit.restarts=3").unwrap().restarts, 3);
        assert_eq!(
            set(&p, "jointfit.method=score").unwrap().method,
            Method::Score
        );
        assert!(set(&p, "jointfit.robust=true").unwrap().robust);
        assert_eq!(
            set(&p, "jointfit.label=knee").unwrap().label.as_deref(),
            Some("knee")
        );
        // Other fields keep their values.
        let q = set(
            &set(&p, "jointfit.alpha=0.3").unwrap(),
            "jointfit.restarts=4",
        )
        .unwrap();
        assert_eq!((q.alpha, q.restarts), (0.3, 4));
    }

    #[test]
    fn errors_name_the_field_and_the_valid_ones() {
        let p = P::default();
        let e = set(&p, "jointfit.alpah=0.3").unwrap_err().to_string();
        assert!(e.contains("alpah") && e.contains("valid: alpha"), "{e}");
        assert!(e.contains("restarts"), "{e}");
        let e = set(&p, "jointfit.restarts=many").unwrap_err().to_string();
        assert!(e.contains("jointfit.restarts"), "{e}");
        let e = set(&p, "jointfit.restarts=1.5").unwrap_err().to_string();
        assert!(e.contains("jointfit.restarts"), "{e}");
        let e = set(&p, "jointfit.method=best").unwrap_err().to_string();
        assert!(e.contains("best") || e.contains("variant"), "{e}");
        let e = set(&p, "jointfit.alpha.x=1").unwrap_err().to_string();
        assert!(e.contains("no fields"), "{e}");
    }
}
