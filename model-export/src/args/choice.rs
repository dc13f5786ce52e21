//! Library enums chosen by name on the command line (the libraries know no clap: each such
//! enum lists its values and names, and this module makes a clap parser of them).
use clap::builder::{PossibleValuesParser, TypedValueParser};

/// A library enum with a fixed set of values, each with its command-line name.
pub trait Named: Sized + Copy + Send + Sync + 'static {
    /// Every value, in the order `--help` lists them.
    const ALL: &'static [Self];
    /// The value's name on the command line.
    fn name(self) -> &'static str;
}

/// The clap parser of a [`Named`] enum: accepts exactly the names (listed by `--help` and
/// in the error for any other word).
pub fn named<T: Named>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::ALL.iter().map(|v| v.name())).try_map(|s| {
        T::ALL
            .iter()
            .copied()
            .find(|v| v.name() == s)
            .ok_or_else(|| format!("unknown value '{s}'"))
    })
}

macro_rules! named {
    ($($t:ty),* $(,)?) => {$(
        impl Named for $t {
            const ALL: &'static [Self] = &<$t>::ALL;
            fn name(self) -> &'static str {
                <$t>::name(self)
            }
        }
    )*};
}

named!(
    excitation::Criterion,
    excitation::Repair,
    fw_export::Precision,
    fw_export::WeightsIn,
    firmware::nn::format::FeaturePreset,
);
