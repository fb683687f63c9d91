//! The one table of semantic classes: what the class image's ids mean, the
//! colour each is painted in the label picture, and how they fold into
//! World-on-Rails' six training classes.

/// A semantic class id as written in the class image (one byte per pixel).
pub type ClassId = u8;

/// One row of the class table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SemanticClass {
    /// The id written in the class image.
    pub id: ClassId,
    /// A short name for logs and legends.
    pub name: &'static str,
    /// The colour of this class in the label picture (sRGB).
    pub label_rgb: [u8; 3],
    /// Whether the class wins a supersampled pixel when any subsample shows
    /// it (small, safety-relevant objects: lamps), instead of the majority.
    pub small_object: bool,
    /// The WoR training class this one folds into.
    pub wor: WorClass,
}

/// World-on-Rails' six segmentation classes (docs/protocol.md §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum WorClass {
    /// Everything not listed below.
    Background = 0,
    /// Drivable road.
    Road = 1,
    /// Painted lane markings.
    LaneMarking = 2,
    /// Vehicles.
    Vehicle = 3,
    /// Pedestrians.
    Pedestrian = 4,
    /// Traffic lights (pole, housing, lamps).
    TrafficLight = 5,
}

/// Number of WoR training classes.
pub const WOR_CLASS_COUNT: usize = 6;

/// Sky and anything never drawn (the clear value).
pub const SKY: ClassId = 0;
/// Road surface.
pub const ROAD: ClassId = 1;
/// Painted lane marking.
pub const LANE_MARKING: ClassId = 2;
/// Sidewalk surface and curb.
pub const SIDEWALK: ClassId = 3;
/// Buildings and other static structure (street-lamp poles included).
pub const BUILDING: ClassId = 4;
/// Vehicles (NPC traffic).
pub const VEHICLE: ClassId = 5;
/// Pedestrians.
pub const PEDESTRIAN: ClassId = 6;
/// Traffic-light pole, housing and unlit lamps.
pub const LIGHT_POLE: ClassId = 7;
/// A lit red lamp.
pub const LAMP_RED: ClassId = 8;
/// A lit yellow lamp.
pub const LAMP_YELLOW: ClassId = 9;
/// A lit green lamp.
pub const LAMP_GREEN: ClassId = 10;
/// Trees.
pub const VEGETATION: ClassId = 11;
/// Crosswalk stripes.
pub const CROSSWALK: ClassId = 12;
/// Ground beside the road (grass, dirt).
pub const TERRAIN: ClassId = 13;

/// Every class, indexed by id (`CLASSES[id].id == id`).
pub const CLASSES: [SemanticClass; 14] = [
    class(SKY, "sky", [70, 130, 180], false, WorClass::Background),
    class(ROAD, "road", [128, 64, 128], false, WorClass::Road),
    class(
        LANE_MARKING,
        "lane_marking",
        [157, 234, 50],
        false,
        WorClass::LaneMarking,
    ),
    class(
        SIDEWALK,
        "sidewalk",
        [244, 35, 232],
        false,
        WorClass::Background,
    ),
    class(
        BUILDING,
        "building",
        [70, 70, 70],
        false,
        WorClass::Background,
    ),
    class(VEHICLE, "vehicle", [0, 0, 142], false, WorClass::Vehicle),
    class(
        PEDESTRIAN,
        "pedestrian",
        [220, 20, 60],
        false,
        WorClass::Pedestrian,
    ),
    class(
        LIGHT_POLE,
        "traffic_light_pole",
        [250, 170, 30],
        false,
        WorClass::TrafficLight,
    ),
    class(
        LAMP_RED,
        "lamp_red",
        [255, 0, 0],
        true,
        WorClass::TrafficLight,
    ),
    class(
        LAMP_YELLOW,
        "lamp_yellow",
        [255, 255, 0],
        true,
        WorClass::TrafficLight,
    ),
    class(
        LAMP_GREEN,
        "lamp_green",
        [0, 255, 0],
        true,
        WorClass::TrafficLight,
    ),
    class(
        VEGETATION,
        "vegetation",
        [107, 142, 35],
        false,
        WorClass::Background,
    ),
    class(
        CROSSWALK,
        "crosswalk",
        [255, 255, 255],
        false,
        WorClass::LaneMarking,
    ),
    class(
        TERRAIN,
        "terrain",
        [152, 251, 152],
        false,
        WorClass::Background,
    ),
];

const fn class(
    id: ClassId,
    name: &'static str,
    label_rgb: [u8; 3],
    small_object: bool,
    wor: WorClass,
) -> SemanticClass {
    SemanticClass {
        id,
        name,
        label_rgb,
        small_object,
        wor,
    }
}

/// Number of classes in the table.
pub const CLASS_COUNT: usize = CLASSES.len();

/// The table row for an id, or `None` for an id outside the table.
pub fn class_info(id: ClassId) -> Option<&'static SemanticClass> {
    CLASSES.get(id as usize)
}

/// Folds a class id into WoR's six training classes (unknown ids: background).
pub fn to_wor(id: ClassId) -> WorClass {
    class_info(id).map_or(WorClass::Background, |c| c.wor)
}

/// The label-picture colour of a class id (unknown ids: black).
pub fn label_rgb(id: ClassId) -> [u8; 3] {
    class_info(id).map_or([0, 0, 0], |c| c.label_rgb)
}

/// WoR's class ids (0-5) of a class image painted in label colours ([`label_rgb`]);
/// a colour of no class reads as background.
pub fn wor_of_label_rgb(rgb: &[u8]) -> Vec<u8> {
    // Built once: this runs on every frame of an agent that asks for classes.
    static TABLE: std::sync::OnceLock<Vec<([u8; 3], u8)>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..CLASS_COUNT as ClassId)
            .map(|id| (label_rgb(id), to_wor(id) as u8))
            .collect()
    });
    rgb.chunks_exact(3)
        .map(|px| {
            table
                .iter()
                .find(|(c, _)| c[..] == *px)
                .map_or(WorClass::Background as u8, |&(_, w)| w)
        })
        .collect()
}

/// The colour of a WoR class id (0-5) in pictures of class images: its
/// main class's label colour (road, lane marking, vehicle, pedestrian,
/// traffic-light pole), black for background and for ids past 5.
pub fn wor_rgb(id: u8) -> [u8; 3] {
    let main = match id {
        x if x == WorClass::Road as u8 => ROAD,
        x if x == WorClass::LaneMarking as u8 => LANE_MARKING,
        x if x == WorClass::Vehicle as u8 => VEHICLE,
        x if x == WorClass::Pedestrian as u8 => PEDESTRIAN,
        x if x == WorClass::TrafficLight as u8 => LIGHT_POLE,
        _ => return [0, 0, 0],
    };
    label_rgb(main)
}

/// Whether a class id is a lit lamp of any colour.
pub fn is_lamp(id: ClassId) -> bool {
    matches!(id, LAMP_RED | LAMP_YELLOW | LAMP_GREEN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_indexed_by_id_and_names_are_unique() {
        for (i, c) in CLASSES.iter().enumerate() {
            assert_eq!(c.id as usize, i, "{} is out of place", c.name);
        }
        let mut names: Vec<_> = CLASSES.iter().map(|c| c.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), CLASS_COUNT);
    }

    #[test]
    fn wor_mapping_folds_as_protocol_says() {
        assert_eq!(to_wor(SKY), WorClass::Background);
        assert_eq!(to_wor(ROAD), WorClass::Road);
        let painted: Vec<u8> = [ROAD, VEHICLE, SKY]
            .iter()
            .flat_map(|&c| label_rgb(c))
            .collect();
        assert_eq!(
            wor_of_label_rgb(&painted),
            vec![
                WorClass::Road as u8,
                WorClass::Vehicle as u8,
                WorClass::Background as u8
            ]
        );
        assert_eq!(to_wor(LANE_MARKING), WorClass::LaneMarking);
        assert_eq!(to_wor(CROSSWALK), WorClass::LaneMarking);
        assert_eq!(to_wor(VEHICLE), WorClass::Vehicle);
        assert_eq!(to_wor(PEDESTRIAN), WorClass::Pedestrian);
        for id in [LIGHT_POLE, LAMP_RED, LAMP_YELLOW, LAMP_GREEN] {
            assert_eq!(to_wor(id), WorClass::TrafficLight);
        }
        for id in [SIDEWALK, BUILDING, VEGETATION, TERRAIN, 200] {
            assert_eq!(to_wor(id), WorClass::Background);
        }
    }

    #[test]
    fn each_wor_class_has_its_own_colour_of_a_class_folding_into_it() {
        let colours: Vec<[u8; 3]> = (0..WOR_CLASS_COUNT as u8).map(wor_rgb).collect();
        for (i, c) in colours.iter().enumerate() {
            assert!(!colours[..i].contains(c), "class {i} shares {c:?}");
            if i > 0 {
                let folded = CLASSES.iter().find(|k| k.label_rgb == *c).unwrap();
                assert_eq!(folded.wor as usize, i, "{}", folded.name);
            }
        }
        assert_eq!(wor_rgb(0), [0, 0, 0]);
        assert_eq!(wor_rgb(6), [0, 0, 0]);
    }

    #[test]
    fn only_lamps_are_small_objects() {
        for c in CLASSES {
            assert_eq!(c.small_object, is_lamp(c.id), "{}", c.name);
        }
    }
}
