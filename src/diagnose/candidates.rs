//! Which effects a diagnosis tries: every effect of every kind the registry knows that the
//! calibration lacks — a robot-wide kind once, an axis kind on every axis, a pair kind on
//! every ordered axis pair — in the registry's order (the contract table's, then the kinds
//! registered at run time). Kinds defined by the data (learned functions) are proposed by
//! `diagnose::learn` instead.

use crate::model::registry::{kinds, Arity, EffectName};
use crate::model::Model;

/// Every effect name of every enumerable kind (62 for the contract table on six axes).
pub fn all_effects() -> Vec<EffectName> {
    let mut names = Vec::new();
    for kind in kinds() {
        let p = kind.prefix;
        let spelled: Vec<String> = match kind.arity {
            Arity::Robot => vec![p.to_string()],
            Arity::Axis => (1..=6).map(|n| format!("{p}:A{n}")).collect(),
            // Defined by the data, not enumerable: `diagnose::learn` proposes one.
            Arity::Spec => continue,
            Arity::Pair => (1..=6)
                .flat_map(|m| {
                    (1..=6)
                        .filter(move |&n| n != m)
                        .map(move |n| format!("{p}:A{m}->A{n}"))
                })
                .collect(),
        };
        names.extend(spelled.iter().filter_map(|s| EffectName::parse(s).ok()));
    }
    names
}

/// The effects of the table that `model` does not have.
pub fn missing(model: &Model) -> Vec<EffectName> {
    let present: Vec<String> = model.effects().iter().map(|e| e.name()).collect();
    all_effects()
        .into_iter()
        .filter(|n| !present.contains(&n.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{Payload, RobotDescription};
    use crate::model::{expand_list, GridOptions};
    use nalgebra::Vector3;

    #[test]
    fn the_table_has_62_effects_and_the_paper_model_lacks_48() {
        let all = all_effects();
        // geometric + 6 map + 6 backlash + 30 crosstalk + 6 compliance + 6 loadplay + 6 tilt
        // + drift
        assert_eq!(all.len(), 1 + 6 + 6 + 30 + 6 + 6 + 6 + 1);
        assert_eq!(all[0].to_string(), "geometric");
        assert!(all.iter().any(|n| n.to_string() == "crosstalk:A2->A3"));
        let mut m = Model::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            Vector3::zeros(),
        );
        for n in expand_list("geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2").unwrap() {
            m.push_named(&n, &GridOptions::default()).unwrap();
        }
        let missing: Vec<String> = missing(&m).iter().map(|n| n.to_string()).collect();
        assert_eq!(missing.len(), 62 - 14);
        assert!(!missing.contains(&"crosstalk:A3->A2".to_string()));
        assert!(missing.contains(&"crosstalk:A2->A3".to_string()));
        assert_eq!(missing.last().unwrap(), "drift");
    }
}
