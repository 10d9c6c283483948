//! Closed sets of named values (a choice parameter's options, a report's labels): a plain
//! enum whose variants and persisted names are listed once, by the `choices!` macro, so a node reads
//! its enum and never compares the names itself.

/// A plain enum whose values are persisted by name. Implement it with the `choices!` macro, which
/// keeps [`Choice::NAMES`] and [`Choice::ALL`] in step.
pub trait Choice: Copy + PartialEq + 'static {
    /// Persisted names, in the order of [`Choice::ALL`].
    const NAMES: &'static [&'static str];
    /// Every value, in the order of [`Choice::NAMES`].
    const ALL: &'static [Self];

    /// The persisted name of `self`.
    fn name(self) -> &'static str;

    /// The value persisted as `name`.
    fn from_name(name: &str) -> Option<Self> {
        let index = Self::NAMES.iter().position(|n| *n == name)?;
        Self::ALL.get(index).copied()
    }
}

/// `'value' is not one of a, b, c`: what a choice says of a name outside `names`.
pub fn not_one_of(value: &str, names: &[&str]) -> String {
    format!("'{value}' is not one of {}", names.join(", "))
}

/// Whether `name` is one of `names`, at compile time (a choice parameter's default is
/// checked where it is declared).
pub const fn is_one_of(name: &str, names: &[&str]) -> bool {
    let mut i = 0;
    while i < names.len() {
        if bytes_equal(name.as_bytes(), names[i].as_bytes()) {
            return true;
        }
        i += 1;
    }
    false
}

const fn bytes_equal(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Implements [`Choice`] from one list of `Variant = "name"` pairs, for an existing
/// fieldless enum (`choices!(UpAxis { Y = "y", Z = "z" });`) or for one it declares
/// (`choices! { enum Top { Open = "open", Closed = "closed" } }`, a plain `Copy` enum).
/// The generated [`Choice::name`] is an exhaustive `match`, so a variant left out does
/// not compile.
macro_rules! choices {
    ($(#[$meta:meta])* $vis:vis enum $ty:ident { $($(#[$vmeta:meta])* $variant:ident = $name:literal),+ $(,)? }) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        $vis enum $ty {
            $($(#[$vmeta])* $variant),+
        }
        $crate::model::choice::choices!($ty { $($variant = $name),+ });
    };
    ($ty:ident { $($variant:ident = $name:literal),+ $(,)? }) => {
        impl $crate::model::choice::Choice for $ty {
            const NAMES: &'static [&'static str] = &[$($name),+];
            const ALL: &'static [Self] = &[$($ty::$variant),+];
            fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }
        }
    };
}
pub(crate) use choices;

choices! {
    /// A switch: the value of every `"on"` / `"off"` choice.
    pub enum OnOff {
        /// Enabled.
        On = "on",
        /// Disabled.
        Off = "off",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    choices! {
        enum Axis { Y = "y", Z = "z" }
    }

    #[test]
    fn names_and_values_round_trip_and_unknown_names_are_refused() {
        assert_eq!(Axis::from_name("z"), Some(Axis::Z));
        assert_eq!(Axis::Y.name(), "y");
        assert_eq!(Axis::from_name("x"), None);
        assert_eq!(Axis::from_name("Y"), None, "names are case-sensitive, as graph files are");
        assert_eq!(not_one_of("x", Axis::NAMES), "'x' is not one of y, z");
        assert!(is_one_of("z", Axis::NAMES));
        assert!(!is_one_of("zz", Axis::NAMES) && !is_one_of("", Axis::NAMES));
        assert_eq!(OnOff::from_name("off"), Some(OnOff::Off));
    }
}
