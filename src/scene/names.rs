//! The named choices a scene or the command line makes: effects and LOD
//! schemes here, back ends and graphics APIs where those stages live. Each
//! is an enum whose names are written once, in the `named!` invocation that
//! declares it; parsing (scene files and flags alike), printing, the lists
//! in error messages and clap's choices all come from that one list.

/// Declares a `Copy` enum with one name per variant, and with it `ALL`,
/// `name()`, `FromStr` (whose error lists the names), serde (as the name)
/// and `clap::ValueEnum`.
macro_rules! named {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident ($what:literal) {
            $( $(#[$vmeta:meta])* $variant:ident => $text:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        $vis enum $name {
            $( $(#[$vmeta])* $variant, )+
        }

        impl $name {
            /// Every choice, in the order the documentation lists them.
            pub const ALL: &'static [$name] = &[$($name::$variant),+];

            /// The name scene files and the command line use.
            pub fn name(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }

            /// Every name, comma-separated, for error messages.
            pub fn names() -> String {
                Self::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", ")
            }
        }

        impl std::str::FromStr for $name {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                Self::ALL
                    .iter()
                    .copied()
                    .find(|v| v.name() == s)
                    .ok_or_else(|| format!("unknown {} '{s}' (known: {})", $what, Self::names()))
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = <String as serde::Deserialize>::deserialize(d)?;
                s.parse().map_err(serde::de::Error::custom)
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }

        impl clap::ValueEnum for $name {
            fn value_variants<'a>() -> &'a [Self] {
                Self::ALL
            }
            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    };
}
#[allow(unused_imports)] // for the stages that declare their own choices
pub(crate) use named;

named! {
    /// An effect a scene may list. One the scene does not list costs
    /// nothing: its varyings are not computed and its shader code is
    /// compiled out.
    pub enum Effect ("effect") {
        /// Diffuse lighting from per-vertex normals.
        Lambert => "lambert",
        /// A Blinn–Phong highlight.
        Phong => "phong",
        /// Exponential fog, per vertex.
        Fog => "fog",
        /// Holkner's ray-traced lightmap.
        Shadows => "shadows",
        /// Per-level normal maps at twice the resolution.
        NormalMap => "normal-map",
        /// A colour per clipmap level.
        LevelTint => "level-tint",
        /// Triangle edges.
        Wireframe => "wireframe",
        /// Geomorphing across level boundaries.
        Morph => "morph",
    }
}

named! {
    /// A level-of-detail scheme.
    pub enum LodScheme ("scheme") {
        /// Geometry clipmaps, this project.
        Clipmap => "clipmap",
        /// Every heightmap vertex: the accuracy reference.
        BruteForce => "brute-force",
        /// de Boer's GeoMipMapping.
        Geomipmap => "geomipmap",
        /// Duchaineau's ROAM.
        Roam => "roam",
        /// Strugar's CDLOD.
        Cdlod => "cdlod",
        /// A "draping" annulus.
        Annulus => "annulus",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_known_ones() {
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>(), Ok(*e));
        }
        for s in LodScheme::ALL {
            assert_eq!(s.to_string().parse::<LodScheme>(), Ok(*s));
        }
        assert_eq!(Effect::ALL.len(), 8);
        assert_eq!(LodScheme::ALL.len(), 6);
        let e = "bloom".parse::<Effect>().unwrap_err();
        assert_eq!(
            e,
            "unknown effect 'bloom' (known: lambert, phong, fog, shadows, normal-map, \
             level-tint, wireframe, morph)"
        );
        assert!("Clipmap".parse::<LodScheme>().is_err(), "names are exact");
    }
}
