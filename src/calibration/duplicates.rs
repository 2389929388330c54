//! Refusing a JSON key given twice in one object: a JSON reader keeps one of the two values
//! (`"dx21": 0.06, "dx21": 40` would move every target by 40 mm), so a calibration with one
//! is ambiguous. Checked over the whole file before it is read, by a pass of its own that
//! names the key's JSON path and its place.

use serde::de::{self, DeserializeSeed, MapAccess, SeqAccess, Visitor};

/// Checks `text` (JSON) for a key given twice in one object; the error is placed by the JSON
/// reader (line, column just after the second key).
pub fn check(text: &str) -> Result<(), serde_json::Error> {
    let mut de = serde_json::Deserializer::from_str(text);
    // Deep nesting is the JSON reader's to refuse (its recursion limit applies here too).
    Path(String::new()).deserialize(&mut de)?;
    de.end()
}

/// The JSON path of the value being checked (`effects[1].parameters`).
struct Path(String);

impl<'de> DeserializeSeed<'de> for Path {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Path {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("any JSON value")
    }

    fn visit_bool<E>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        Ok(())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0;
        while seq
            .next_element_seed(Path(format!("{}[{i}]", self.0)))?
            .is_some()
        {
            i += 1;
        }
        Ok(())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = std::collections::HashSet::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = if self.0.is_empty() {
                key.clone()
            } else {
                format!("{}.{key}", self.0)
            };
            if !seen.insert(key) {
                return Err(de::Error::custom(format!(
                    "`{path}` is given twice in one object: which value is meant? (remove one)"
                )));
            }
            map.next_value_seed(Path(path))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_given_twice_is_named_with_its_path_and_line() {
        assert!(check(r#"{"a": {"b": 1, "c": [1, {"d": 2}]}, "e": null}"#).is_ok());
        let text = "{\"effects\": [{}, {\"parameters\": {\"dx21\": 0.06,\n \"dx21\": 40}}]}";
        let e = check(text).unwrap_err();
        assert!(
            e.to_string()
                .contains("`effects[1].parameters.dx21` is given twice"),
            "{e}"
        );
        assert_eq!(e.line(), 2);
        // The same key in two objects is no duplicate.
        assert!(check(r#"[{"a": 1}, {"a": 2}]"#).is_ok());
    }
}
