//! Enumerations that users name in text (methods, fills, engines, error kinds, CSG and
//! morphology operations, kernels, formats): each lists its values and their names once, by
//! implementing [`Named`] — most through [`named_enum!`](crate::named_enum), where one row per
//! value declares the variant and its name together. Parsing, `Display`, serde, error messages,
//! the command line's possible values and the OpenAPI enums test all read that list.
//!
//! Not here: what a value means or does (that stays with the type's module), and tables with
//! more columns than a name (error kinds carry a status and a title: `app/error.rs`).

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

/// Declares a closed set as one table: the enum, each variant with its name, and from that table
/// [`Named`] (so parsing, `Display` and serde), plus inherent `ALL` (an array, so `for m in
/// Method::ALL` yields values) and `name()` for callers without the trait in scope.
///
/// ```ignore
/// named_enum! {
///     /// What a voxel being set means.
///     pub enum Method: "method" {
///         /// The voxel centre is inside.
///         Solid = "solid",
///         Surface = "surface",
///     }
/// }
/// ```
#[macro_export]
macro_rules! named_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident : $what:literal {
            $( $(#[$vmeta:meta])* $variant:ident = $text:literal ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $name { $( $(#[$vmeta])* $variant ),+ }

        impl $name {
            /// Every value, in the order messages and `--help` list them.
            pub const ALL: [$name; [$(stringify!($variant)),+].len()] = [$($name::$variant),+];
            /// The value's name, as users write it.
            pub fn name(self) -> &'static str {
                match self { $($name::$variant => $text),+ }
            }
        }

        impl $crate::names::Named for $name {
            const WHAT: &'static str = $what;
            const ALL: &'static [$name] = &$name::ALL;
            fn name(self) -> &'static str {
                $name::name(self)
            }
        }

        $crate::impl_named!($name);
    };
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
    crate::named_enum! {
        /// A set for the macro's own test.
        enum Tint: "tint" {
            Red = "red",
            /// Documented variants keep their docs.
            Green = "green",
            Blue = "blue",
        }
    }

    #[test]
    fn one_table_gives_names_parsing_and_messages() {
        assert_eq!(Tint::ALL, [Tint::Red, Tint::Green, Tint::Blue]);
        assert_eq!(Tint::Green.name(), "green");
        assert_eq!(Tint::Blue.to_string(), "blue");
        assert_eq!("red".parse::<Tint>(), Ok(Tint::Red));
        assert_eq!(
            "teal".parse::<Tint>(),
            Err("unknown tint \"teal\"; expected red, green or blue".to_string())
        );
        assert_eq!(serde_json::to_string(&Tint::Green).unwrap(), "\"green\"");
        assert_eq!(
            serde_json::from_str::<Tint>("\"blue\"").unwrap(),
            Tint::Blue
        );
        assert_eq!(super::choices::<Tint>(), "red, green or blue");
    }

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
