//! The names of the values a user types (backends, scenes, layouts, proxy modes, grid
//! structures, colourings): one list per enum ([`Named`]), read alike on the command line, in
//! scene files and in reports, in any case.
//!
//! The `mochi` tool builds the library with the `clap` feature, which derives
//! `clap::ValueEnum` on these enums (each value's help on the command line is the first
//! paragraph of its doc); the library's tests check that both give every value the same name.

/// An enum whose values have names.
pub trait Named: Sized + Copy + 'static {
    /// Every value, in the order lists and errors give them.
    const ALL: &'static [Self];

    /// The value's name.
    fn name(self) -> &'static str;
}

/// `impl Named for $type` from its values' names, in the order they are listed (also an
/// inherent `name` and `Display`, which print the name).
macro_rules! named {
    ($type:ty { $($value:ident => $name:literal),+ $(,)? }) => {
        impl $crate::names::Named for $type {
            const ALL: &'static [Self] = &[$(<$type>::$value),+];

            fn name(self) -> &'static str {
                match self {
                    $(<$type>::$value => $name),+
                }
            }
        }

        impl $type {
            /// Name, as on the command line and in scene files.
            pub fn name(self) -> &'static str {
                $crate::names::Named::name(self)
            }
        }

        impl std::fmt::Display for $type {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }
    };
}
pub(crate) use named;

/// The name of `value`.
pub fn name<T: Named>(value: &T) -> &'static str {
    value.name()
}

/// The value of `T` named `name` in any case, or an error naming `what` and listing the names.
pub fn parse<T: Named>(name: &str, what: &str) -> Result<T, String> {
    T::ALL
        .iter()
        .copied()
        .find(|value| value.name().eq_ignore_ascii_case(name))
        .ok_or_else(|| {
            let names: Vec<&str> = T::ALL.iter().map(|v| v.name()).collect();
            let (last, rest) = names.split_last().expect("an enum has values");
            format!("unknown {what} {name:?}: use {} or {last}", rest.join(", "))
        })
}

/// A serde module for fields of a [`Named`] type (`#[serde(with = "mochi::names::by_name")]`):
/// written as the name, read in any case, any other name refused with the list of names.
pub mod by_name {
    use super::Named;
    use serde::de::Error as _;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes the name of `value`.
    pub fn serialize<T: Named, S: Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(value.name())
    }

    /// Reads a name in any case, refusing any other than those of `T`, which the error lists.
    pub fn deserialize<'de, T: Named, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
        let name = String::deserialize(d)?;
        super::parse(&name, "value").map_err(D::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    enum Fruit {
        Apple,
        BloodOrange,
    }

    named!(Fruit { Apple => "apple", BloodOrange => "blood-orange" });

    #[test]
    fn names_are_read_in_any_case_and_others_refused_with_the_list() {
        assert_eq!(Fruit::ALL, [Fruit::Apple, Fruit::BloodOrange]);
        assert_eq!(Fruit::BloodOrange.to_string(), "blood-orange");
        assert_eq!(
            parse::<Fruit>("Blood-ORANGE", "fruit"),
            Ok(Fruit::BloodOrange)
        );
        assert_eq!(
            parse::<Fruit>("pear", "fruit"),
            Err("unknown fruit \"pear\": use apple or blood-orange".to_owned())
        );
        #[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
        struct Basket {
            #[serde(with = "by_name")]
            fruit: Fruit,
        }
        let basket: Basket = serde_json::from_str(r#"{"fruit": "APPLE"}"#).unwrap();
        assert_eq!(basket.fruit, Fruit::Apple);
        assert_eq!(
            serde_json::to_string(&basket).unwrap(),
            r#"{"fruit":"apple"}"#
        );
        let refused = serde_json::from_str::<Basket>(r#"{"fruit": "kiwi"}"#).unwrap_err();
        assert!(
            refused.to_string().contains("use apple or blood-orange"),
            "{refused}"
        );
    }
}
