//! One table of names per enum: [`name_table!`] gives an enum of named values (a sky model, a
//! pixel format, a demosaic method, ...) its list `ALL`, `name()`, `names()` for the "allowed
//! ..." of a message, `from_name()`, and clap's [`ValueEnum`](clap::ValueEnum), all from one
//! `Variant => "name"` table beside the enum. The command line, scene files, the Python package
//! and the dataset description accept the names of that table; a variant missing from it does
//! not compile (`name()` matches every variant).
//!
//! ```
//! use psns::sky::PolarizationModel;
//! assert_eq!(PolarizationModel::ALL.len(), PolarizationModel::names().split(", ").count());
//! assert_eq!(PolarizationModel::from_name(" Queen "), Some(PolarizationModel::Queen));
//! assert_eq!(PolarizationModel::Queen.name(), "queen");
//! ```

/// Implements the name table of an enum: `name_table!(Type { Variant => "name", ... })`, every
/// variant once, in the order the command line lists them.
macro_rules! name_table {
    ($ty:ident { $($v:ident => $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every value, in the order of its name table.
            pub const ALL: [$ty; [$($name),+].len()] = [$($ty::$v),+];

            /// The name on the command line, in scene files and in dataset descriptions.
            pub const fn name(self) -> &'static str {
                match self {
                    $($ty::$v => $name),+
                }
            }

            /// Every name, comma-separated, in the order of [`Self::ALL`].
            pub fn names() -> String {
                [$($name),+].join(", ")
            }

            /// The value of a name (case-insensitive, surrounding spaces ignored).
            pub fn from_name(s: &str) -> Option<Self> {
                let t = s.trim();
                Self::ALL
                    .into_iter()
                    .find(|v| v.name().eq_ignore_ascii_case(t))
            }
        }

        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                &Self::ALL
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    };
}

pub(crate) use name_table;
