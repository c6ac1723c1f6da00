//! The names ASAM OpenDRIVE (1.4 to 1.8) defines for the elements rtr reads: each element's
//! attributes and child elements. The reader refuses any other name inside these elements, so
//! a misspelt `<roadmark>`, `<widht>` or `colour=` is an error instead of a record dropped in
//! silence. Children the standard defines but rtr does not read (objects, signals, elevation,
//! `<userData>`, ...) are allowed and their subtrees skipped; vendor extensions (`<t_*>`, names
//! of no OpenDRIVE revision) are refused.
//!
//! Namespaced attributes (`xsi:schemaLocation` and the like) belong to XML, not to OpenDRIVE,
//! and are not checked.

use roxmltree::Node;

/// One element rtr reads, as the standard defines it.
pub(super) struct Element {
    pub name: &'static str,
    pub attributes: &'static [&'static str],
    pub children: &'static [Child],
    /// Unknown children are left to the reader, which refuses them with a message of its own
    /// (the plan-view shapes: "unsupported planView geometry").
    pub reader_refuses_others: bool,
}

/// A child element the standard allows.
pub(super) enum Child {
    /// rtr reads it: its attributes and children are checked in turn.
    Read(&'static Element),
    /// Standard, but rtr does not read it: its subtree is skipped.
    Skipped(&'static str),
}

impl Child {
    fn name(&self) -> &'static str {
        match self {
            Child::Read(e) => e.name,
            Child::Skipped(name) => name,
        }
    }
}

/// The standard's "additional data", allowed in every element.
const ADDITIONAL_DATA: [&str; 3] = ["userData", "include", "dataQuality"];

const fn element(
    name: &'static str,
    attributes: &'static [&'static str],
    children: &'static [Child],
) -> Element {
    Element {
        name,
        attributes,
        children,
        reader_refuses_others: false,
    }
}

use Child::{Read, Skipped};

pub(super) static OPENDRIVE: Element = element(
    "OpenDRIVE",
    &[],
    &[
        Read(&HEADER),
        Read(&ROAD),
        Skipped("controller"),
        Read(&JUNCTION),
        Skipped("junctionGroup"),
        Skipped("station"),
    ],
);

static HEADER: Element = element(
    "header",
    &[
        "revMajor", "revMinor", "name", "version", "date", "north", "south", "east", "west",
        "vendor",
    ],
    &[
        Skipped("geoReference"),
        Skipped("offset"),
        Skipped("license"),
        Skipped("defaultRegulations"),
    ],
);

static ROAD: Element = element(
    "road",
    &["name", "length", "id", "junction", "rule"],
    &[
        Read(&ROAD_LINK),
        Read(&ROAD_TYPE),
        Read(&PLAN_VIEW),
        Skipped("elevationProfile"),
        Skipped("lateralProfile"),
        Read(&LANES),
        Skipped("objects"),
        Skipped("signals"),
        Skipped("surface"),
        Skipped("railroad"),
    ],
);

static ROAD_LINK: Element = element(
    "link",
    &[],
    &[
        Read(&ROAD_PREDECESSOR),
        Read(&ROAD_SUCCESSOR),
        Skipped("neighbor"),
    ],
);

const ROAD_LINK_ATTRIBUTES: &[&str] = &[
    "elementType",
    "elementId",
    "contactPoint",
    "elementS",
    "elementDir",
];
static ROAD_PREDECESSOR: Element = element("predecessor", ROAD_LINK_ATTRIBUTES, &[]);
static ROAD_SUCCESSOR: Element = element("successor", ROAD_LINK_ATTRIBUTES, &[]);

static ROAD_TYPE: Element = element("type", &["s", "type", "country"], &[Read(&ROAD_SPEED)]);
static ROAD_SPEED: Element = element("speed", &["max", "unit"], &[]);

static PLAN_VIEW: Element = element("planView", &[], &[Read(&GEOMETRY)]);
static GEOMETRY: Element = Element {
    name: "geometry",
    attributes: &["s", "x", "y", "hdg", "length"],
    children: &[
        Read(&LINE),
        Read(&ARC),
        Read(&SPIRAL),
        Read(&POLY3),
        Read(&PARAM_POLY3),
    ],
    reader_refuses_others: true,
};
static LINE: Element = element("line", &[], &[]);
static ARC: Element = element("arc", &["curvature"], &[]);
static SPIRAL: Element = element("spiral", &["curvStart", "curvEnd"], &[]);
static POLY3: Element = element("poly3", &["a", "b", "c", "d"], &[]);
static PARAM_POLY3: Element = element(
    "paramPoly3",
    &["aU", "bU", "cU", "dU", "aV", "bV", "cV", "dV", "pRange"],
    &[],
);

static LANES: Element = element("lanes", &[], &[Read(&LANE_OFFSET), Read(&LANE_SECTION)]);
static LANE_OFFSET: Element = element("laneOffset", &["s", "a", "b", "c", "d"], &[]);
static LANE_SECTION: Element = element(
    "laneSection",
    &["s", "singleSide"],
    &[Read(&LEFT), Read(&CENTER), Read(&RIGHT)],
);
static LEFT: Element = element("left", &[], &[Read(&LANE)]);
static CENTER: Element = element("center", &[], &[Read(&LANE)]);
static RIGHT: Element = element("right", &[], &[Read(&LANE)]);

static LANE: Element = element(
    "lane",
    &[
        "id",
        "type",
        "level",
        // 1.8:
        "direction",
        "advisory",
        "dynamicLaneDirection",
        "dynamicLaneType",
        "roadWorks",
    ],
    &[
        Read(&LANE_LINK),
        Skipped("border"),
        Read(&WIDTH),
        Read(&ROAD_MARK),
        Skipped("material"),
        // 1.4 and 1.5 only.
        Skipped("visibility"),
        Read(&LANE_SPEED),
        Skipped("access"),
        Skipped("height"),
        Skipped("rule"),
    ],
);
static LANE_LINK: Element = element(
    "link",
    &[],
    &[Read(&LANE_PREDECESSOR), Read(&LANE_SUCCESSOR)],
);
static LANE_PREDECESSOR: Element = element("predecessor", &["id"], &[]);
static LANE_SUCCESSOR: Element = element("successor", &["id"], &[]);
static WIDTH: Element = element("width", &["sOffset", "a", "b", "c", "d"], &[]);
static ROAD_MARK: Element = element(
    "roadMark",
    &[
        "sOffset",
        "type",
        "weight",
        "color",
        "material",
        "width",
        "laneChange",
        "height",
    ],
    &[Skipped("type"), Skipped("explicit"), Skipped("sway")],
);
static LANE_SPEED: Element = element("speed", &["sOffset", "max", "unit"], &[]);

static JUNCTION: Element = element(
    "junction",
    &[
        "id",
        "name",
        "type",
        // Virtual junctions (1.7):
        "mainRoad",
        "sStart",
        "sEnd",
        "orientation",
    ],
    &[
        Read(&CONNECTION),
        Skipped("priority"),
        Skipped("controller"),
        Skipped("surface"),
        // 1.8:
        Skipped("crossPath"),
        Skipped("boundary"),
        Skipped("elevationGrid"),
        Skipped("planView"),
    ],
);
static CONNECTION: Element = element(
    "connection",
    &[
        "id",
        "incomingRoad",
        "connectingRoad",
        "contactPoint",
        "type",
        // Direct junctions (1.7):
        "linkedRoad",
    ],
    &[
        Read(&LANE_LINK_IN_JUNCTION),
        // Virtual connections (1.5 to 1.6):
        Skipped("predecessor"),
        Skipped("successor"),
    ],
);
static LANE_LINK_IN_JUNCTION: Element = element("laneLink", &["from", "to", "overlapZone"], &[]);

/// The first name under `node` (an instance of `schema`) that the standard does not define
/// there: the element to blame and the message.
pub(super) fn first_unknown<'a, 'input>(
    node: Node<'a, 'input>,
    schema: &Element,
) -> Option<(Node<'a, 'input>, String)> {
    let tag = schema.name;
    for attribute in node.attributes().filter(|a| a.namespace().is_none()) {
        let name = attribute.name();
        if !schema.attributes.contains(&name) {
            let expected = if schema.attributes.is_empty() {
                "none".to_string()
            } else {
                format!("one of {}", schema.attributes.join(", "))
            };
            return Some((
                node,
                format!(
                    "<{tag}> has attribute `{name}`, which OpenDRIVE does not define for \
                     <{tag}>{}; expected {expected}",
                    hint(name, schema.attributes.iter().copied())
                ),
            ));
        }
    }
    for child in node.children().filter(Node::is_element) {
        let name = child.tag_name().name();
        if ADDITIONAL_DATA.contains(&name) {
            continue;
        }
        match schema.children.iter().find(|c| c.name() == name) {
            Some(Read(inner)) => {
                if let Some(found) = first_unknown(child, inner) {
                    return Some(found);
                }
            }
            Some(Skipped(_)) => {}
            None if schema.reader_refuses_others => {}
            None => {
                let names = || {
                    schema
                        .children
                        .iter()
                        .map(Child::name)
                        .chain(ADDITIONAL_DATA)
                };
                return Some((
                    child,
                    format!(
                        "<{tag}> has child <{name}>, which OpenDRIVE does not define in \
                         <{tag}>{}; expected one of {}",
                        hint(name, names()),
                        names().collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
        }
    }
    None
}

/// Whether `node` is the standard's additional data (`<userData>`, `<include>`,
/// `<dataQuality>`), allowed in every element and never read.
pub(super) fn is_additional_data(node: Node) -> bool {
    ADDITIONAL_DATA.contains(&node.tag_name().name())
}

/// " (did you mean `x`?)" where `name` differs from a standard name only in case.
fn hint(name: &str, mut known: impl Iterator<Item = &'static str>) -> String {
    known
        .find(|k| k.eq_ignore_ascii_case(name))
        .map(|k| format!(" (did you mean `{k}`?)"))
        .unwrap_or_default()
}
