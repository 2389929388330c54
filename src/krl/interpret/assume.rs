//! What the user states about run time (`--assume NAME=VALUE`): the value of a variable, an
//! array element or an input (`lnUsedBase=2`, `$IN[5]=TRUE`, `nStation=#LEFT`) that the walk
//! cannot know before the program runs — a station, and so a base, chosen by the cell's PLC.
//! The walk takes an assumption wherever it reads the name and the program leaves the value
//! open: a value only known at run time, or the stored initial value of a declaration (the
//! data list holds the last value, which run time may change). A value the program itself
//! assigns on the walk still counts. How often each was used is counted, so that the summary
//! can list them and an assumption never used can be said.

use std::fmt;

use super::value::Value;

/// One `NAME=VALUE`.
#[derive(Clone, Debug, PartialEq)]
pub struct Assumption {
    /// The name in capitals (KRL names are case-insensitive), without its index.
    pub name: Vec<u8>,
    /// The index of an array element or input (`$IN[5]`: `[5]`), empty for a variable.
    pub index: Vec<i64>,
    pub value: Assumed,
    /// As the user wrote it (for messages).
    pub written: String,
}

/// The value assumed.
#[derive(Clone, Debug, PartialEq)]
pub enum Assumed {
    Bool(bool),
    Int(i64),
    Real(f64),
    /// `#NAME`, without the `#`, in capitals.
    Enum(Vec<u8>),
}

impl Assumption {
    /// The walk's value of it.
    pub fn value<'f>(&self) -> Value<'f> {
        match &self.value {
            Assumed::Bool(b) => Value::Bool(*b),
            Assumed::Int(i) => Value::Int(*i),
            Assumed::Real(r) => Value::Real(*r),
            Assumed::Enum(e) => Value::Enum(e.clone()),
        }
    }

    /// Whether it is the value of `name` (capitals) at `index`.
    pub fn is(&self, name: &[u8], index: &[i64]) -> bool {
        self.name == name && self.index == index
    }
}

impl fmt::Display for Assumption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.written)
    }
}

impl std::str::FromStr for Assumption {
    type Err = String;

    /// `NAME=VALUE`, `NAME[i]=VALUE`, `NAME[i,j]=VALUE`; VALUE `TRUE`, `FALSE`, an integer,
    /// a real or `#NAME`.
    fn from_str(text: &str) -> Result<Assumption, String> {
        let (lhs, rhs) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}`: expected NAME=VALUE (lnUsedBase=2, $IN[5]=TRUE)"))?;
        let lhs = lhs.trim();
        let (name, index) = match lhs.split_once('[') {
            Some((n, rest)) => {
                let inner = rest
                    .strip_suffix(']')
                    .ok_or_else(|| format!("`{lhs}`: expected NAME[i] with a closing ]"))?;
                let index = inner
                    .split(',')
                    .map(|i| i.trim().parse::<i64>())
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|_| {
                        format!("`{lhs}`: an index must be whole numbers (NAME[5], NAME[1,2])")
                    })?;
                (n.trim(), index)
            }
            None => (lhs, Vec::new()),
        };
        let is_name = !name.is_empty()
            && name
                .bytes()
                .next()
                .is_some_and(|b| b.is_ascii_alphabetic() || b == b'_' || b == b'$')
            && name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'$');
        if !is_name {
            return Err(format!("`{name}` is not a KRL name"));
        }
        let v = rhs.trim();
        let value = if v.eq_ignore_ascii_case("TRUE") {
            Assumed::Bool(true)
        } else if v.eq_ignore_ascii_case("FALSE") {
            Assumed::Bool(false)
        } else if let Some(e) = v.strip_prefix('#') {
            if e.is_empty() || !e.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
                return Err(format!("`{v}`: an enum value is #NAME"));
            }
            Assumed::Enum(e.to_ascii_uppercase().into_bytes())
        } else if let Ok(i) = v.parse::<i64>() {
            Assumed::Int(i)
        } else {
            match v.parse::<f64>() {
                Ok(r) if r.is_finite() => Assumed::Real(r),
                _ => {
                    return Err(format!(
                        "`{v}`: expected TRUE, FALSE, a number or #NAME as the value of {name}"
                    ))
                }
            }
        };
        Ok(Assumption {
            name: name.to_ascii_uppercase().into_bytes(),
            index,
            value,
            written: format!("{lhs}={v}"),
        })
    }
}

/// How often each assumption of a walk was used, in the order given.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Used(pub Vec<u64>);

impl Used {
    pub fn add(&mut self, other: &Used) {
        if self.0.len() < other.0.len() {
            self.0.resize(other.0.len(), 0);
        }
        for (a, b) in self.0.iter_mut().zip(&other.0) {
            *a += b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_names_indices_and_values() {
        let a: Assumption = "lnUsedBase=2".parse().unwrap();
        assert_eq!((a.name.as_slice(), a.index.len()), (&b"LNUSEDBASE"[..], 0));
        assert_eq!(a.value, Assumed::Int(2));
        let a: Assumption = "$in[5] = true".parse().unwrap();
        assert_eq!(
            (a.name.as_slice(), a.index.as_slice()),
            (&b"$IN"[..], &[5][..])
        );
        assert_eq!(a.value, Assumed::Bool(true));
        assert_eq!(a.written, "$in[5]=true");
        let a: Assumption = "P[1, 2]=-0.5".parse().unwrap();
        assert_eq!(
            (a.index.as_slice(), a.value.clone()),
            (&[1, 2][..], Assumed::Real(-0.5))
        );
        let a: Assumption = "side=#left".parse().unwrap();
        assert_eq!(a.value, Assumed::Enum(b"LEFT".to_vec()));
        for bad in [
            "x", "=1", "1a=2", "x[a]=1", "x[1=1", "x=", "x=maybe", "x=#", "x=inf",
        ] {
            assert!(bad.parse::<Assumption>().is_err(), "{bad}");
        }
    }
}
