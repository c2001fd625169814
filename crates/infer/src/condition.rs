//! The object-level condition of a predicted latent: what is known about an object before it is
//! touched, from a small fixed vocabulary the velocity model's manifest names (`fields` of its
//! `object` condition input):
//!
//! - `category:<name>`: 1 when the object is of that category, else 0. An object's category is
//!   its camera name (`cup`) or the part of it before the first `_` (`fabric_a` -> `fabric`).
//! - `<field>`: the camera's value `<object>_<field>` from the VisualObservation (the message's
//!   names: `cup_width_m`, `fabric_a_edge_height_m`, `fabric_a_roughness`, SI units), 0 when the
//!   camera has no such value for the object (a cup has no `edge_height_m`).
//!
//! A value the camera could not estimate (NaN) or that is not finite is an error: the condition
//! would be a guess. All zeros is the unconditional branch (no object), which the model saw in
//! training through classifier-free dropout.

use thiserror::Error;
use unitac_core::msg::VisualObservation;

/// The prefix of a category field.
pub const CATEGORY: &str = "category:";

#[derive(Debug, Clone, PartialEq, Error)]
pub enum ConditionError {
    #[error(
        "object '{object}' is of category '{category}', which the model's fields {fields:?} do not name"
    )]
    UnknownCategory {
        object: String,
        category: String,
        fields: Vec<String>,
    },
    #[error("the camera's {name} is {value} (not a measurement)")]
    NotFinite { name: String, value: f64 },
}

/// The category of a camera object name.
pub fn category(object: &str) -> &str {
    object.split('_').next().unwrap_or(object)
}

/// The object-level condition of `object` for `fields`.
pub fn object_condition(
    fields: &[String],
    object: &str,
    visual: &VisualObservation,
) -> Result<Vec<f32>, ConditionError> {
    let cat = category(object);
    if !fields.iter().any(|f| f.strip_prefix(CATEGORY) == Some(cat)) {
        return Err(ConditionError::UnknownCategory {
            object: object.into(),
            category: cat.into(),
            fields: fields.to_vec(),
        });
    }
    fields
        .iter()
        .map(|f| {
            if let Some(c) = f.strip_prefix(CATEGORY) {
                return Ok(if c == cat { 1.0 } else { 0.0 });
            }
            let name = format!("{object}_{f}");
            match visual.names.iter().position(|n| *n == name) {
                None => Ok(0.0),
                Some(i) => {
                    let v = visual.values.get(i).copied().unwrap_or(f64::NAN);
                    if v.is_finite() {
                        Ok(v as f32)
                    } else {
                        Err(ConditionError::NotFinite { name, value: v })
                    }
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_core::Stamp;
    use unitac_core::msg::Header;

    fn fields() -> Vec<String> {
        [
            "category:cup",
            "category:fabric",
            "width_m",
            "edge_height_m",
        ]
        .map(String::from)
        .to_vec()
    }
    fn visual(names: &[&str], values: &[f64]) -> VisualObservation {
        VisualObservation {
            header: Header::new(Stamp(0), "camera"),
            names: names.iter().map(|s| s.to_string()).collect(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn a_cup_and_a_fabric_fill_their_own_fields() {
        let v = visual(
            &[
                "cup_width_m",
                "fabric_a_edge_height_m",
                "fabric_b_edge_height_m",
            ],
            &[0.07, 0.004, 0.006],
        );
        assert_eq!(
            object_condition(&fields(), "cup", &v).unwrap(),
            vec![1.0, 0.0, 0.07, 0.0]
        );
        assert_eq!(
            object_condition(&fields(), "fabric_b", &v).unwrap(),
            vec![0.0, 1.0, 0.0, 0.006]
        );
    }

    #[test]
    fn unknown_categories_and_unmeasured_values_are_errors() {
        let v = visual(&["cup_width_m"], &[f64::NAN]);
        assert!(matches!(
            object_condition(&fields(), "cup", &v),
            Err(ConditionError::NotFinite { .. })
        ));
        assert!(matches!(
            object_condition(&fields(), "bottle", &v),
            Err(ConditionError::UnknownCategory { .. })
        ));
    }
}
