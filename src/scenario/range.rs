//! Parameter ranges of logical scenarios and the seeded sampler that turns them into the
//! concrete values of one scenario, recording each draw under its name.

use std::collections::BTreeMap;
use std::fmt;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::{Deserialize, Serialize, Serializer};

/// A logical-scenario parameter: a fixed number, or `[low, high]` drawn uniformly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Range {
    Fixed(f64),
    Uniform(f64, f64),
}

impl Range {
    pub fn low(&self) -> f64 {
        match *self {
            Range::Fixed(v) | Range::Uniform(v, _) => v,
        }
    }

    pub fn high(&self) -> f64 {
        match *self {
            Range::Fixed(v) | Range::Uniform(_, v) => v,
        }
    }

    /// Checks the bounds are finite and lie within `[min, max]`.
    pub fn check(&self, name: &str, min: f64, max: f64) -> Result<(), String> {
        let (lo, hi) = (self.low(), self.high());
        if !(lo.is_finite() && hi.is_finite()) || lo > hi {
            return Err(format!(
                "`{name}` = {self}: expected finite bounds, low <= high"
            ));
        }
        if lo < min || hi > max {
            return Err(format!(
                "`{name}` = {self}: expected values within [{min}, {max}]"
            ));
        }
        Ok(())
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Range::Fixed(v) => write!(f, "{v}"),
            Range::Uniform(lo, hi) => write!(f, "[{lo}, {hi}]"),
        }
    }
}

impl Serialize for Range {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match *self {
            Range::Fixed(v) => s.serialize_f64(v),
            Range::Uniform(lo, hi) => [lo, hi].serialize(s),
        }
    }
}

/// Written by hand (not `#[serde(untagged)]`) so a wrong value gets a message that says what
/// was expected instead of "did not match any variant".
impl<'de> Deserialize<'de> for Range {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct RangeVisitor;
        impl<'de> Visitor<'de> for RangeVisitor {
            type Value = Range;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or a [low, high] range")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Range, E> {
                Ok(Range::Fixed(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Range, E> {
                Ok(Range::Fixed(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Range, E> {
                Ok(Range::Fixed(v as f64))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Range, A::Error> {
                let lo: f64 = seq
                    .next_element()?
                    .ok_or_else(|| de::Error::invalid_length(0, &self))?;
                let hi: f64 = seq
                    .next_element()?
                    .ok_or_else(|| de::Error::invalid_length(1, &self))?;
                if seq.next_element::<f64>()?.is_some() {
                    return Err(de::Error::invalid_length(3, &self));
                }
                Ok(Range::Uniform(lo, hi))
            }
        }
        d.deserialize_any(RangeVisitor)
    }
}

/// Rounds to 1e-6 (a micrometre, a micro-second): concrete scenarios store only such values,
/// because serde_json parses numbers of up to 15 significant digits exactly but may miss the
/// last bit of a 17-digit one, and a scenario must read back bit for bit.
pub fn quantize(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// Draws concrete values from ranges with a seeded ChaCha8 generator (portable: the same seed
/// gives the same numbers on every platform) and records every draw by name.
pub struct Sampler {
    pub rng: ChaCha8Rng,
    pub drawn: BTreeMap<String, f64>,
}

impl Sampler {
    pub fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            drawn: BTreeMap::new(),
        }
    }

    /// A value of `range`, recorded as `name`.
    pub fn draw(&mut self, name: &str, range: &Range) -> f64 {
        let v = match *range {
            Range::Fixed(v) => v,
            Range::Uniform(lo, hi) if hi > lo => self.rng.random_range(lo..=hi),
            Range::Uniform(lo, _) => lo,
        };
        let v = quantize(v);
        self.drawn.insert(name.to_string(), v);
        v
    }

    /// A uniform number in [0, 1) that is not a named parameter (e.g. background placement).
    pub fn unit(&mut self) -> f64 {
        quantize(self.rng.random::<f64>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Holder {
        v: Range,
    }

    #[test]
    fn ranges_parse_from_numbers_and_pairs_with_clear_errors() {
        let fixed: Holder = toml::from_str("v = 3").unwrap();
        assert_eq!(fixed.v, Range::Fixed(3.0));
        let pair: Holder = toml::from_str("v = [1.5, 2]").unwrap();
        assert_eq!(pair.v, Range::Uniform(1.5, 2.0));
        let err = toml::from_str::<Holder>("v = \"fast\"")
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("a number or a [low, high] range"), "{err}");
        let err = toml::from_str::<Holder>("v = [1, 2, 3]")
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("a number or a [low, high] range"), "{err}");
        assert!(Range::Uniform(2.0, 1.0).check("v", 0.0, 10.0).is_err());
        assert!(Range::Uniform(1.0, 20.0).check("v", 0.0, 10.0).is_err());
    }

    #[test]
    fn sampling_is_seeded_and_recorded() {
        let r = Range::Uniform(0.0, 10.0);
        let mut a = Sampler::new(7);
        let mut b = Sampler::new(7);
        let mut c = Sampler::new(8);
        let (va, vb, vc) = (a.draw("x", &r), b.draw("x", &r), c.draw("x", &r));
        assert_eq!(va, vb);
        assert_ne!(va, vc);
        assert!((0.0..=10.0).contains(&va));
        assert_eq!(a.drawn["x"], va);
    }
}
