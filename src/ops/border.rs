//! What a step does with the vertices of an open border: one vocabulary for every step that
//! has a `boundary` parameter (`smooth`, `relax`, `fair`, `decimate`), each step taking the
//! modes that make sense for it.
//!
//! Rule: a name says what happens to the border, and means the same in every step. Before
//! this vocabulary each step had its own enum, and `"free"` meant "smoothed along the border"
//! in `smooth` but "moves like an interior vertex" in `decimate`. The older spellings stay
//! accepted, each in the step that had it ([`Dialect`]), so that shipped and users' recipes
//! still parse and mean what they meant.
//!
//! The resolved recipe (the form that is recorded and hashed) keeps each step's older
//! spelling: the daemon's job key is the scan set's hash with the recipe's, so a changed
//! spelling would queue every scan already processed again, and jobs queued before an upgrade
//! would fail the worker's recipe-hash check.

use serde::{Deserialize, Serialize};

/// The border modes. The serde spelling (kebab-case) is the name in a recipe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Border {
    /// Border vertices stay where they are; `decimate` also never removes them. Every
    /// border loop is kept exactly.
    Fixed,
    /// Each border loop is smoothed as a curve of its own: its vertices move along the
    /// border, not into the surface (`smooth`: averaged over their border neighbours;
    /// `relax`/`fair`: the thesis' curve fairing, ch. 4).
    Curve,
    /// Border vertices slide along their border, held by perpendicular border planes
    /// weighted by `boundary_weight` (`decimate`, as MeshLab's `BoundaryWeight`).
    Weighted,
    /// Border vertices move like interior ones (`decimate`; its topology guards still
    /// apply).
    LikeInterior,
}

impl Border {
    /// The name in a recipe, from serde.
    pub fn name(self) -> String {
        crate::text::serde_name(&self)
    }
}

/// The modes one step takes, each with the spelling the step's resolved recipe records
/// (see the module note for why that is the older spelling).
pub struct Dialect {
    pub step: &'static str,
    pub modes: &'static [(Border, &'static str)],
}

/// `smooth`: `"free"` was its name for [`Border::Curve`].
pub const SMOOTH: Dialect = Dialect {
    step: "smooth",
    modes: &[(Border::Fixed, "fixed"), (Border::Curve, "free")],
};

/// `relax` and `fair`: `"fair"` was their name for [`Border::Curve`].
pub const FAIRING: Dialect = Dialect {
    step: "relax and fair",
    modes: &[(Border::Curve, "fair"), (Border::Fixed, "fixed")],
};

/// `decimate`: `"keep"` was its name for [`Border::Fixed`], `"free"` for
/// [`Border::LikeInterior`].
pub const DECIMATE: Dialect = Dialect {
    step: "decimate",
    modes: &[
        (Border::Fixed, "keep"),
        (Border::Weighted, "weighted"),
        (Border::LikeInterior, "free"),
    ],
};

impl Dialect {
    /// A mode from its name or the step's older spelling of it.
    pub fn parse(&self, name: &str) -> Result<Border, String> {
        self.modes
            .iter()
            .find(|(mode, recorded)| *recorded == name || mode.name() == name)
            .map(|(mode, _)| *mode)
            .ok_or_else(|| {
                // Begins as serde's own message, which the recipe's error line finder reads.
                format!(
                    "unknown variant `{name}`, expected one of {} (boundary of {})",
                    self.choices(),
                    self.step
                )
            })
    }

    /// The spelling the resolved recipe records.
    pub fn recorded(&self, mode: Border) -> &'static str {
        self.modes
            .iter()
            .find(|(m, _)| *m == mode)
            .map_or("unsupported", |(_, recorded)| recorded)
    }

    /// Refuses a mode the step does not take (possible only from code, not from a recipe).
    pub fn check(&self, mode: Border) -> Result<(), String> {
        if self.modes.iter().any(|(m, _)| *m == mode) {
            Ok(())
        } else {
            Err(format!(
                "boundary = \"{}\" does not apply to {}; expected one of {}",
                mode.name(),
                self.step,
                self.choices()
            ))
        }
    }

    fn choices(&self) -> String {
        let names: Vec<String> = self
            .modes
            .iter()
            .map(|(mode, recorded)| match mode.name() {
                name if name == *recorded => format!("`{name}`"),
                name => format!("`{name}` (or `{recorded}`)"),
            })
            .collect();
        names.join(", ")
    }

    fn serialize<S: serde::Serializer>(&self, mode: Border, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.recorded(mode))
    }

    fn deserialize<'de, D: serde::Deserializer<'de>>(&self, d: D) -> Result<Border, D::Error> {
        let name = String::deserialize(d)?;
        self.parse(&name).map_err(serde::de::Error::custom)
    }
}

/// `#[serde(with = "…")]` modules, one per dialect, for a `Border` field.
macro_rules! dialect_module {
    ($module:ident, $dialect:ident) => {
        pub mod $module {
            use super::{Border, $dialect};

            pub fn serialize<S: serde::Serializer>(mode: &Border, s: S) -> Result<S::Ok, S::Error> {
                $dialect.serialize(*mode, s)
            }

            pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Border, D::Error> {
                $dialect.deserialize(d)
            }
        }
    };
}

dialect_module!(smooth, SMOOTH);
dialect_module!(fairing, FAIRING);
dialect_module!(decimate, DECIMATE);

/// `Option<Border>` in `smooth`'s recipe form.
pub mod smooth_option {
    use super::{Border, SMOOTH};
    use serde::Deserialize;

    pub fn serialize<S: serde::Serializer>(mode: &Option<Border>, s: S) -> Result<S::Ok, S::Error> {
        match mode {
            Some(mode) => SMOOTH.serialize(*mode, s),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<Border>, D::Error> {
        let name = String::deserialize(d)?;
        SMOOTH
            .parse(&name)
            .map(Some)
            .map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_dialect_takes_the_new_names_and_its_own_old_ones() {
        assert_eq!(SMOOTH.parse("curve"), Ok(Border::Curve));
        assert_eq!(SMOOTH.parse("free"), Ok(Border::Curve));
        assert_eq!(FAIRING.parse("fair"), Ok(Border::Curve));
        assert_eq!(FAIRING.parse("fixed"), Ok(Border::Fixed));
        assert_eq!(DECIMATE.parse("keep"), Ok(Border::Fixed));
        assert_eq!(DECIMATE.parse("fixed"), Ok(Border::Fixed));
        assert_eq!(DECIMATE.parse("free"), Ok(Border::LikeInterior));
        assert_eq!(DECIMATE.parse("like-interior"), Ok(Border::LikeInterior));
        // A name another step takes is refused with this step's choices.
        let e = SMOOTH.parse("weighted").unwrap_err();
        assert!(e.starts_with("unknown variant `weighted`"), "{e}");
        assert!(e.contains("`curve` (or `free`)"), "{e}");
        assert!(DECIMATE.parse("curve").is_err());
        assert!(DECIMATE.check(Border::Curve).is_err());
        assert!(FAIRING.check(Border::Curve).is_ok());
    }

    #[test]
    fn the_recorded_spelling_is_the_older_one() {
        assert_eq!(SMOOTH.recorded(Border::Curve), "free");
        assert_eq!(FAIRING.recorded(Border::Curve), "fair");
        assert_eq!(DECIMATE.recorded(Border::Fixed), "keep");
        assert_eq!(DECIMATE.recorded(Border::LikeInterior), "free");
        assert_eq!(Border::LikeInterior.name(), "like-interior");
    }
}
