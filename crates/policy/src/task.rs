//! The task string (LeRobot `task`), parsed with a small fixed grammar at load:
//!
//! ```text
//! pick the <smoother|rougher|softer|harder|flatter|bumpier> <object>   (fabric selection)
//! squeeze the cup [by <number> <cm|mm>]                                 (cup deformation)
//! ```
//! Case and surrounding blanks do not matter; anything else is a load-time error.

use thiserror::Error;

/// What the task asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Task {
    /// Choose between two touched objects by a property.
    Pick {
        /// As in PropertyComparison.property: hardness | roughness | texture.
        property: &'static str,
        /// true: the one with MORE of the property (rougher, harder, bumpier).
        more: bool,
        /// The word after the adjective, e.g. `fabric`.
        object: String,
    },
    /// Squeeze the cup; `by_m`: the loss of diameter the task names \[m] (None: the scene's).
    Squeeze { by_m: Option<f64> },
}

#[derive(Debug, Clone, PartialEq, Error)]
#[error(
    "task '{0}' is not understood (say 'pick the smoother|rougher|softer|harder|flatter|bumpier <object>' or 'squeeze the cup [by N cm|mm]')"
)]
pub struct TaskError(pub String);

const ADJECTIVES: &[(&str, &str, bool)] = &[
    ("smoother", "roughness", false),
    ("rougher", "roughness", true),
    ("softer", "hardness", false),
    ("harder", "hardness", true),
    ("flatter", "texture", false),
    ("bumpier", "texture", true),
];

/// Largest deformation a task may name \[m].
pub const MAX_SQUEEZE_M: f64 = 0.05;

impl Task {
    pub fn parse(text: &str) -> Result<Task, TaskError> {
        let err = || TaskError(text.to_string());
        let lower = text.trim().to_ascii_lowercase();
        let words: Vec<&str> = lower.split_whitespace().collect();
        match words.as_slice() {
            ["pick", "the", adj, object] => {
                let (_, property, more) = ADJECTIVES
                    .iter()
                    .find(|(a, _, _)| a == adj)
                    .ok_or_else(err)?;
                if !object
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_')
                {
                    return Err(err());
                }
                Ok(Task::Pick {
                    property,
                    more: *more,
                    object: object.to_string(),
                })
            }
            ["squeeze", "the", "cup"] => Ok(Task::Squeeze { by_m: None }),
            ["squeeze", "the", "cup", "by", n, unit] => {
                let n: f64 = n.parse().map_err(|_| err())?;
                let scale = match *unit {
                    "cm" => 0.01,
                    "mm" => 0.001,
                    _ => return Err(err()),
                };
                let by = n * scale;
                if !(by.is_finite() && by > 0.0 && by <= MAX_SQUEEZE_M) {
                    return Err(err());
                }
                Ok(Task::Squeeze { by_m: Some(by) })
            }
            _ => Err(err()),
        }
    }

    /// true for the fabric-selection family (a choice between touched objects).
    pub fn is_pick(&self) -> bool {
        matches!(self, Task::Pick { .. })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_grammar() {
        assert_eq!(
            Task::parse("Pick the smoother fabric").unwrap(),
            Task::Pick {
                property: "roughness",
                more: false,
                object: "fabric".into()
            }
        );
        assert_eq!(
            Task::parse("  pick the harder sponge ").unwrap(),
            Task::Pick {
                property: "hardness",
                more: true,
                object: "sponge".into()
            }
        );
        assert_eq!(
            Task::parse("squeeze the cup").unwrap(),
            Task::Squeeze { by_m: None }
        );
        assert_eq!(
            Task::parse("squeeze the cup by 5 mm").unwrap(),
            Task::Squeeze { by_m: Some(0.005) }
        );
        for bad in [
            "",
            "pick the nicer fabric",
            "pick the smoother",
            "squeeze the cup by 1 inch",
            "squeeze the cup by -1 cm",
            "squeeze the cup by NaN cm",
            "squeeze the cup by 9 cm",
            "pick the smoother fab/ric",
        ] {
            assert!(Task::parse(bad).is_err(), "{bad}");
        }
        assert_eq!(
            Task::parse("dance").unwrap_err().to_string(),
            "task 'dance' is not understood (say 'pick the smoother|rougher|softer|harder|flatter|bumpier <object>' or 'squeeze the cup [by N cm|mm]')"
        );
    }
}
