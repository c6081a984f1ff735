//! Enumerations that users name in text (methods, fills, CSG and morphology operations, kernels,
//! formats): each lists its values and their names once, by implementing [`Named`]. Parsing,
//! error messages, serde and the command line's possible values all come from that list.

/// A closed set of values, each with one name.
pub trait Named: Copy + Sized + 'static {
    /// What a value is, for messages ("method", "fill", ...).
    const WHAT: &'static str;
    /// Every value, in the order messages list them.
    const ALL: &'static [Self];
    fn name(self) -> &'static str;
}

/// `a, b or c`.
pub fn choices<T: Named>() -> String {
    let names: Vec<&str> = T::ALL.iter().map(|v| v.name()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

/// The value named `s`, or a message listing the names.
pub fn parse<T: Named>(s: &str) -> Result<T, String> {
    T::ALL
        .iter()
        .copied()
        .find(|v| v.name() == s)
        .ok_or_else(|| format!("unknown {} {s:?}; expected {}", T::WHAT, choices::<T>()))
}

/// Implements `FromStr`, `Display`, `Serialize` and `Deserialize` by name for [`Named`] types.
#[macro_export]
macro_rules! impl_named {
    ($($t:ty),* $(,)?) => {$(
        impl std::str::FromStr for $t {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                $crate::names::parse(s)
            }
        }
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str($crate::names::Named::name(*self))
            }
        }
        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str($crate::names::Named::name(*self))
            }
        }
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = <std::borrow::Cow<'de, str>>::deserialize(d)?;
                $crate::names::parse(&s).map_err(serde::de::Error::custom)
            }
        }
    )*};
}

/// Three comma-separated values `X,Y,Z` (grid origins and dims on the command line and in
/// query strings).
pub fn parse_triple<T: std::str::FromStr>(s: &str) -> Result<[T; 3], String> {
    let parts: Vec<T> = s
        .split(',')
        .map(|p| p.trim().parse::<T>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected three comma-separated numbers X,Y,Z, got {s:?}"))?;
    parts
        .try_into()
        .map_err(|_| format!("expected three comma-separated numbers X,Y,Z, got {s:?}"))
}

#[cfg(test)]
mod tests {
    #[test]
    fn triples() {
        assert_eq!(
            super::parse_triple::<f64>("1, -2,3.5"),
            Ok([1.0, -2.0, 3.5])
        );
        assert!(super::parse_triple::<u32>("1,2").is_err());
        assert!(super::parse_triple::<u32>("1,2,-3").is_err());
        assert!(super::parse_triple::<u32>("1,2,3,4").is_err());
    }
}
