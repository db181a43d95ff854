//! Fixed-length arrays in scene and style files, read whole. Serde reads `[T; N]` as a tuple of
//! its first N entries, and the `toml` crate does not check that none follow, so a colour of
//! four numbers or a position of four coordinates lost the last one without a word. Fields of
//! fixed length are read through [`exact`] (and [`exact_option`], [`exact_list`]), which count
//! every entry and refuse any other number of them.

use std::fmt;
use std::marker::PhantomData;

use serde::de::{self, Deserialize, Deserializer, IgnoredAny, SeqAccess, Visitor};

/// `[T; N]` read from an array of exactly N entries.
struct Exact<T, const N: usize>([T; N]);

impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_seq(ExactVisitor(PhantomData))
    }
}

struct ExactVisitor<T, const N: usize>(PhantomData<T>);

impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Visitor<'de>
    for ExactVisitor<T, N>
{
    type Value = Exact<T, N>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "an array of {N} entries")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut out = [T::default(); N];
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = seq
                .next_element()?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        // Skipped, not kept: a file's length bounds how many there are.
        let mut found = N;
        while seq.next_element::<IgnoredAny>()?.is_some() {
            found += 1;
        }
        if found > N {
            return Err(de::Error::invalid_length(found, &self));
        }
        Ok(Exact(out))
    }
}

/// A `[T; N]` field (`#[serde(deserialize_with = "exact")]`).
pub(crate) fn exact<'de, D, T, const N: usize>(deserializer: D) -> Result<[T; N], D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Copy + Default,
{
    Exact::deserialize(deserializer).map(|Exact(array)| array)
}

/// An optional `[T; N]` field (`#[serde(default, deserialize_with = "exact_option")]`).
pub(crate) fn exact_option<'de, D, T, const N: usize>(
    deserializer: D,
) -> Result<Option<[T; N]>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Copy + Default,
{
    exact(deserializer).map(Some)
}

/// An optional list of `[T; N]` (`#[serde(default, deserialize_with = "exact_list")]`).
pub(crate) fn exact_list<'de, D, T, const N: usize>(
    deserializer: D,
) -> Result<Option<Vec<[T; N]>>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Copy + Default,
{
    let list: Vec<Exact<T, N>> = Vec::deserialize(deserializer)?;
    Ok(Some(list.into_iter().map(|Exact(array)| array).collect()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize)]
    struct Fields {
        #[serde(deserialize_with = "exact")]
        position: [f64; 3],
        #[serde(default, deserialize_with = "exact_option")]
        range: Option<[f64; 2]>,
        #[serde(default, deserialize_with = "exact_list")]
        stops: Option<Vec<[f64; 3]>>,
    }

    fn read(text: &str) -> Result<Fields, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    }

    #[test]
    fn arrays_of_the_stated_length_are_read_and_any_other_refused() {
        let fields = read("position = [1, 2, 3]\nstops = [[0, 0, 0], [1, 1, 1]]").unwrap();
        assert_eq!(fields.position, [1.0, 2.0, 3.0]);
        assert_eq!(
            (fields.range, fields.stops.map(|s| s.len())),
            (None, Some(2))
        );
        for (text, length) in [
            (
                "position = [1, 2, 3, 4]",
                "invalid length 4, expected an array of 3 entries",
            ),
            (
                "position = [1, 2]",
                "invalid length 2, expected an array of 3 entries",
            ),
            (
                "position = [1, 2, 3]\nrange = [0, 1, 2]",
                "invalid length 3, expected an array of 2",
            ),
            (
                "position = [1, 2, 3]\nstops = [[0, 0, 0, 9]]",
                "invalid length 4",
            ),
        ] {
            let error = read(text).err().unwrap();
            assert!(error.contains(length), "{text}: {error}");
        }
    }
}
