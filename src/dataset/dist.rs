//! [`Dist`]: the distribution of one parameter, as written in the description's TOML.

use super::*;

/// The distribution of one parameter.
///
/// In TOML: a number (fixed), `{ min = A, max = B }` with an optional `step` (uniform over the
/// grid A, A + step, …, ≤ B; `step = 0` draws a continuous uniform value in [A, B)), or
/// `{ values = [a, b, …] }` (uniform choice).
#[derive(Clone, Debug, PartialEq)]
pub enum Dist {
    /// Always this value.
    Fixed(f64),
    /// Uniform over a grid (or continuous for step 0).
    Uniform {
        /// Smallest value.
        min: f64,
        /// Largest value.
        max: f64,
        /// Grid step; `None` = the parameter's default step.
        step: Option<f64>,
    },
    /// Uniform choice among values.
    Choice(Vec<f64>),
}

impl Serialize for Dist {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Dist::Fixed(v) => s.serialize_f64(*v),
            Dist::Uniform { min, max, step } => {
                let mut m = s.serialize_map(None)?;
                m.serialize_entry("min", min)?;
                m.serialize_entry("max", max)?;
                if let Some(st) = step {
                    m.serialize_entry("step", st)?;
                }
                m.end()
            }
            Dist::Choice(v) => {
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry("values", v)?;
                m.end()
            }
        }
    }
}

impl<'de> Deserialize<'de> for Dist {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        const KEYS: &[&str] = &["min", "max", "step", "values"];
        impl<'de> Visitor<'de> for V {
            type Value = Dist;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, { min = A, max = B, step = S } or { values = [...] }")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<Dist, E> {
                Ok(Dist::Fixed(v as f64))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut m: A) -> std::result::Result<Dist, A::Error> {
                let (mut min, mut max, mut step, mut values) = (None, None, None, None);
                while let Some(k) = m.next_key::<String>()? {
                    match k.as_str() {
                        "min" => min = Some(m.next_value::<f64>()?),
                        "max" => max = Some(m.next_value::<f64>()?),
                        "step" => step = Some(m.next_value::<f64>()?),
                        "values" => values = Some(m.next_value::<Vec<f64>>()?),
                        other => return Err(de::Error::unknown_field(other, KEYS)),
                    }
                }
                match (min, max, step, values) {
                    (Some(min), Some(max), step, None) => Ok(Dist::Uniform { min, max, step }),
                    (None, None, None, Some(v)) => Ok(Dist::Choice(v)),
                    (_, _, _, Some(_)) => Err(de::Error::custom(
                        "give either values = [...] or min/max/step, not both",
                    )),
                    (None, _, _, None) => Err(de::Error::missing_field("min")),
                    (_, None, _, None) => Err(de::Error::missing_field("max")),
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// A uniform distribution over `min..=max` in steps of `step`.
pub(super) fn uniform(min: f64, max: f64, step: f64) -> Dist {
    Dist::Uniform {
        min,
        max,
        step: Some(step),
    }
}

/// Most grid points a uniform distribution may have.
pub(super) const MAX_GRID: f64 = 1e12;

/// Decimal places of a step or bound as written (`0.05` → 2), at most 9.
pub(super) fn decimals(v: f64) -> usize {
    let s = format!("{v}");
    s.split_once('.').map_or(0, |(_, f)| f.len()).min(9)
}

/// `v` rounded to `d` decimal places, as the f64 nearest that decimal (so it prints as written).
pub(super) fn round_decimal(v: f64, d: usize) -> f64 {
    let r: f64 = format!("{v:.d$}").parse().expect("formatted number parses");
    r + 0.0 // -0 prints as "-0"; +0.0 makes it 0
}

impl Dist {
    /// Checks the distribution of parameter `name` against its allowed range `lo..=hi`.
    pub(super) fn validate(&self, name: &str, lo: f64, hi: f64) -> Result<()> {
        match self {
            Dist::Fixed(v) => check_range(name, *v, lo, hi).map(|_| ()),
            Dist::Uniform { min, max, step } => {
                check_range(&format!("{name}.min"), *min, lo, hi)?;
                check_range(&format!("{name}.max"), *max, *min, hi)?;
                if let Some(s) = step {
                    check_range(&format!("{name}.step"), *s, 0.0, hi - lo)?;
                    if *s > 0.0 && (max - min) / s > MAX_GRID {
                        return Err(Error::range(
                            &format!("{name}.step"),
                            *s,
                            &format!(
                                "at least {} (at most 1e12 grid points)",
                                num((max - min) / MAX_GRID)
                            ),
                        ));
                    }
                }
                Ok(())
            }
            Dist::Choice(v) => {
                if v.is_empty() {
                    return Err(Error::Invalid(format!(
                        "{name}.values is empty (give at least one value)"
                    )));
                }
                for x in v {
                    check_range(&format!("{name}.values"), *x, lo, hi)?;
                }
                Ok(())
            }
        }
    }

    /// Draws one value from `rng` (`default_step` for a uniform distribution without a step).
    pub(super) fn draw<R: Rng>(&self, rng: &mut R, default_step: f64) -> f64 {
        match self {
            Dist::Fixed(v) => *v,
            Dist::Choice(v) => v[rng.random_range(0..v.len())],
            Dist::Uniform { min, max, step } => {
                let step = step.unwrap_or(default_step);
                if step == 0.0 || max == min {
                    if max == min {
                        return *min;
                    }
                    return min + (max - min) * rng.random::<f64>();
                }
                let n = ((max - min) / step + 1e-9).floor() as u64;
                let k = rng.random_range(0..=n);
                let d = decimals(step).max(decimals(*min));
                round_decimal(min + k as f64 * step, d).min(*max)
            }
        }
    }
}

/// The distribution of a named value (a sky model, a radiance, a DOP form), parsed by the
/// value's own type as the command line parses it.
///
/// In TOML: a name (always that value, e.g. `model = "rayleigh"`) or `{ values = ["wang",
/// "rayleigh"] }` (uniform choice).
#[derive(Clone, Debug, PartialEq)]
pub enum Pick<T> {
    /// Always this value.
    Fixed(T),
    /// Uniform choice among values (at least one).
    Choice(Vec<T>),
}

impl<T: Copy> Pick<T> {
    /// The value of one draw.
    pub(super) fn draw<R: Rng>(&self, rng: &mut R) -> T {
        match self {
            Pick::Fixed(v) => *v,
            Pick::Choice(v) => v[rng.random_range(0..v.len())],
        }
    }

    /// Every value it can draw.
    pub fn values(&self) -> Vec<T> {
        match self {
            Pick::Fixed(v) => vec![*v],
            Pick::Choice(v) => v.clone(),
        }
    }
}

impl<T: fmt::Display> Serialize for Pick<T> {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Pick::Fixed(v) => s.serialize_str(&v.to_string()),
            Pick::Choice(v) => {
                let names: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry("values", &names)?;
                m.end()
            }
        }
    }
}

impl<'de, T> Deserialize<'de> for Pick<T>
where
    T: std::str::FromStr<Err = Error>,
{
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: std::str::FromStr<Err = Error>> Visitor<'de> for V<T> {
            type Value = Pick<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a name or { values = [\"a\", \"b\", ...] }")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<Pick<T>, E> {
                v.parse().map(Pick::Fixed).map_err(E::custom)
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                mut m: A,
            ) -> std::result::Result<Pick<T>, A::Error> {
                let mut values = None;
                while let Some(k) = m.next_key::<String>()? {
                    match k.as_str() {
                        "values" => values = Some(m.next_value::<Vec<String>>()?),
                        other => return Err(de::Error::unknown_field(other, &["values"])),
                    }
                }
                let values = values.ok_or_else(|| de::Error::missing_field("values"))?;
                if values.is_empty() {
                    return Err(de::Error::custom("values is empty: give at least one"));
                }
                values
                    .iter()
                    .map(|v| v.parse().map_err(de::Error::custom))
                    .collect::<std::result::Result<Vec<T>, _>>()
                    .map(Pick::Choice)
            }
        }
        d.deserialize_any(V(std::marker::PhantomData))
    }
}
