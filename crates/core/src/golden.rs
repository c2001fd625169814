//! Comparing event streams with the committed golden files (tests/golden/*.jsonl).
//!
//! An event stream is the JSON lines `unitac run --events` prints ([`crate::Msg::to_json`]).
//! Two streams agree when they have the same events in the same order with the same fields;
//! integers, strings and booleans must be equal, floats equal within a relative tolerance
//! ([`FLOAT_TOLERANCE`]) because ONNX Runtime may sum in another order on another thread count or
//! CPU. Near zero the tolerance is relative to the field's everyday scale, read from its unit
//! suffix ([`unit_scale`]: a millimetre for `_m`, a square millimetre for `_m2`), so that an SI
//! length or area is compared as tightly as a value of order one. Everything else in the stages
//! is integer or deterministic float code, so in practice the streams are byte-identical on one
//! machine.

use serde_json::Value;

/// Relative tolerance for floats: |a - b| <= tol * max(scale, |a|, |b|), with the field's
/// [`unit_scale`].
pub const FLOAT_TOLERANCE: f64 = 1e-5;

/// The everyday scale of a field by its unit suffix: 1e-3 for lengths (`_m`, `_m_s`), 1e-6 for
/// areas (`_m2`), 1 otherwise.
pub fn unit_scale(field: &str) -> f64 {
    if field.ends_with("_m2") {
        1e-6
    } else if field.ends_with("_m") || field.ends_with("_m_s") {
        1e-3
    } else {
        1.0
    }
}

/// The first difference between two event streams, as one line naming the event and field.
pub fn diff(expected: &[Value], got: &[Value]) -> Option<String> {
    for (i, (e, g)) in expected.iter().zip(got).enumerate() {
        if let Some(d) = diff_value(e, g, "") {
            let kind = e.get("type").and_then(Value::as_str).unwrap_or("?");
            return Some(format!("event {i} ({kind}){d}"));
        }
    }
    (expected.len() != got.len())
        .then(|| format!("{} events expected, {} got", expected.len(), got.len()))
}

fn diff_value(e: &Value, g: &Value, path: &str) -> Option<String> {
    match (e, g) {
        (Value::Object(a), Value::Object(b)) => {
            if a.len() != b.len() || a.keys().any(|k| !b.contains_key(k)) {
                let ka: Vec<&String> = a.keys().collect();
                let kb: Vec<&String> = b.keys().collect();
                return Some(format!("{path}: fields {ka:?} expected, {kb:?} got"));
            }
            a.iter()
                .find_map(|(k, v)| diff_value(v, &b[k], &format!("{path}.{k}")))
        }
        (Value::Array(a), Value::Array(b)) => {
            if a.len() != b.len() {
                return Some(format!(
                    "{path}: {} items expected, {} got",
                    a.len(),
                    b.len()
                ));
            }
            a.iter()
                .zip(b)
                .enumerate()
                .find_map(|(i, (x, y))| diff_value(x, y, &format!("{path}[{i}]")))
        }
        (Value::Number(a), Value::Number(b)) if a.is_f64() || b.is_f64() => {
            let (x, y) = (
                a.as_f64().unwrap_or(f64::NAN),
                b.as_f64().unwrap_or(f64::NAN),
            );
            let field = path.rsplit('.').next().unwrap_or("");
            let field = field.split('[').next().unwrap_or(field);
            let tol = FLOAT_TOLERANCE * unit_scale(field).max(x.abs()).max(y.abs());
            ((x - y).abs() > tol || x.is_nan() != y.is_nan())
                .then(|| format!("{path}: {x} expected, {y} got"))
        }
        _ => (e != g).then(|| format!("{path}: {e} expected, {g} got")),
    }
}

/// A line of a JSON-lines text that is not JSON.
#[derive(Debug, thiserror::Error)]
#[error("line {line}: {source}")]
pub struct LineError {
    /// 1-based.
    pub line: usize,
    pub source: serde_json::Error,
}

/// JSON lines -> values (blank lines skipped); a line that is not JSON is an error naming it.
pub fn parse_lines(text: &str) -> Result<Vec<Value>, LineError> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l).map_err(|source| LineError {
                line: i + 1,
                source,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use serde_json::json;

    #[test]
    fn equal_streams_agree_and_any_change_is_named() {
        let a = vec![
            json!({"type": "contact_episode", "episode_id": 1, "label": "a", "peak": 10.5}),
            json!({"type": "tactile_latent", "data": [0.25, -1.0]}),
        ];
        assert_eq!(diff(&a, &a), None);
        let mut b = a.clone();
        b[1]["data"][1] = json!(-1.000001);
        assert_eq!(diff(&a, &b), None, "within the float tolerance");
        b[1]["data"][1] = json!(-1.1);
        assert!(
            diff(&a, &b)
                .unwrap()
                .contains("event 1 (tactile_latent).data[1]")
        );
        let mut c = a.clone();
        c[0]["episode_id"] = json!(2);
        assert!(diff(&a, &c).unwrap().contains(".episode_id"));
        c = a.clone();
        c[0]["label"] = json!("b");
        assert!(diff(&a, &c).is_some());
        assert!(
            diff(&a, &a[..1])
                .unwrap()
                .contains("2 events expected, 1 got")
        );
        c = a.clone();
        c[0].as_object_mut().unwrap().remove("peak");
        assert!(diff(&a, &c).unwrap().contains("fields"));
    }

    #[test]
    fn si_lengths_and_areas_are_compared_at_their_own_scale() {
        let a =
            vec![json!({"type": "contact_state", "area_m2": 5e-6, "shear_x_m": 2e-4, "s": 5e-6})];
        let moved = |k: &str, v: f64| {
            let mut b = a.clone();
            b[0][k] = json!(v);
            diff(&a, &b)
        };
        // A 10 % change of a 5 mm^2 area or a 0.2 mm shear is caught ...
        assert!(moved("area_m2", 5.5e-6).unwrap().contains(".area_m2"));
        assert!(moved("shear_x_m", 2.2e-4).unwrap().contains(".shear_x_m"));
        // ... a change in the last digits is not, nor one below the floor of a unitless value.
        assert_eq!(moved("area_m2", 5.000001e-6), None);
        assert_eq!(moved("s", 5.5e-6), None);
        assert_eq!(unit_scale("speed_m_s"), 1e-3);
        assert_eq!(unit_scale("strength"), 1.0);
    }

    #[test]
    fn lines_parse_and_bad_lines_are_named() {
        assert_eq!(parse_lines("{\"a\":1}\n\n[2]\n").unwrap().len(), 2);
        let e = parse_lines("{}\nnope\n").unwrap_err();
        assert_eq!(e.line, 2);
        assert!(e.to_string().starts_with("line 2: "), "{e}");
    }
}
