//! Tests of the OpenDRIVE reader and writer on the A9 map and small hand-written documents.

use super::opendrive::*;
use super::to_xodr;
use super::xodr_parse::{parse_xodr, read_xodr};
use crate::Error;

const A9: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/automatum-a9/staticWorld.xodr"
);

fn a9_text() -> String {
    std::fs::read_to_string(A9).expect("A9 map is present")
}

/// The parse error for `text`: (line, message).
fn parse_err(text: &str) -> (usize, String) {
    match parse_xodr(text, "test.xodr") {
        Err(Error::Parse {
            source_name,
            line,
            message,
            ..
        }) => {
            assert_eq!(source_name, "test.xodr");
            (line, message)
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn reads_the_a9_map() {
    let od = parse_xodr(&a9_text(), "a9").expect("parses");
    assert_eq!(od.roads.len(), 1);
    let r = &od.roads[0];
    assert_eq!((r.id.as_str(), r.length), ("0", 266.281170003393));
    assert!(
        matches!(r.geometries[0].kind, GeometryKind::Arc { curvature } if curvature == -0.000322282793482797)
    );
    let sec = &r.lane_sections[0];
    assert_eq!(
        sec.left.iter().map(|l| l.id).collect::<Vec<_>>(),
        vec![1, 2, 3, 4, 5]
    );
    assert_eq!(
        sec.right.iter().map(|l| l.id).collect::<Vec<_>>(),
        vec![-1, -2, -3, -4, -5]
    );
    assert_eq!(sec.right[0].kind, LaneType::None);
    assert_eq!(sec.right[4].kind, LaneType::Shoulder);
    assert_eq!(sec.right[1].road_marks[0].kind, RoadMark::Broken);
    assert_eq!(sec.right[1].speeds[0].max, Some(100.0 / 3.6));
    assert_eq!(r.types[0].speed, Some(100.0 / 3.6));
    assert_eq!(sec.right[2].widths[0].a, 3.6);
}

#[test]
fn round_trips_through_the_writer() {
    let od = parse_xodr(&a9_text(), "a9").expect("parses");
    let again = parse_xodr(&to_xodr(&od), "written").expect("written map parses");
    assert_eq!(od, again);
}

#[test]
fn unsupported_geometry_names_element_and_line() {
    let text = a9_text().replace(
        "<arc curvature=\"-0.000322282793482797\" />",
        "<cubic k=\"1\"/>",
    );
    let (line, msg) = parse_err(&text);
    assert_eq!(line, 12);
    assert!(
        msg.contains("unsupported planView geometry <cubic>"),
        "{msg}"
    );
    assert!(
        msg.contains("line, arc, spiral, poly3, paramPoly3"),
        "{msg}"
    );
}

#[test]
fn bad_numbers_name_element_attribute_and_line() {
    let text = a9_text().replace(
        "length=\"266.281170003393\" id=\"0\"",
        "length=\"abc\" id=\"0\"",
    );
    let (line, msg) = parse_err(&text);
    assert_eq!(line, 6);
    assert!(
        msg.contains("<road> attribute `length`") && msg.contains("\"abc\""),
        "{msg}"
    );
    for bad in ["NaN", "inf", "-inf"] {
        let text = a9_text().replace("a=\"3.6\"", &format!("a=\"{bad}\""));
        let (_, msg) = parse_err(&text);
        assert!(
            msg.contains("<width> attribute `a`") && msg.contains("finite"),
            "{msg}"
        );
    }
    let text = a9_text().replace("hdg=\"1.60149666833748\" ", "");
    let (line, msg) = parse_err(&text);
    assert_eq!(line, 11);
    assert!(
        msg.contains("<geometry> is missing required attribute `hdg`"),
        "{msg}"
    );
    let text = a9_text().replace("id=\"-3\"", "id=\"minus three\"");
    assert!(parse_err(&text).1.contains("expected an integer"));
}

#[test]
fn border_lanes_and_bad_structure_are_errors() {
    let text = a9_text().replace(
        "<width sOffset=\"0\" a=\"3.6\" b=\"0\" c=\"0\" d=\"0\" />",
        "<border sOffset=\"0\" a=\"3.6\" b=\"0\" c=\"0\" d=\"0\" />",
    );
    let (_, msg) = parse_err(&text);
    assert!(msg.contains("lane -3 is described by <border>"), "{msg}");
    assert!(
        parse_err("<OpenDRIVE><road")
            .1
            .contains("not well-formed XML")
    );
    assert!(parse_err("<map/>").1.contains("expected <OpenDRIVE>"));
    let text = a9_text().replace(
        "unit=\"km/h\" />\n        </type>",
        "unit=\"furlongs\" />\n        </type>",
    );
    assert!(parse_err(&text).1.contains("`unit`"));
    let text = a9_text().replace("<lane id=\"-3\"", "<lane id=\"-7\"");
    assert!(parse_err(&text).1.contains("consecutive"));
}

#[test]
fn reads_links_junctions_and_other_geometries() {
    let text = r#"<OpenDRIVE><header/>
<road id="a" length="30" junction="-1">
 <link><predecessor elementType="junction" elementId="j"/>
   <successor elementType="road" elementId="b" contactPoint="end"/></link>
 <type s="0" type="motorway"><speed max="60" unit="mph"/></type>
 <planView>
  <geometry s="0" x="0" y="0" hdg="0" length="10"><spiral curvStart="0" curvEnd="0.01"/></geometry>
  <geometry s="10" x="10" y="0" hdg="0" length="10"><poly3 a="0" b="0" c="0.001" d="0"/></geometry>
  <geometry s="20" x="20" y="0" hdg="0" length="10"><paramPoly3 aU="0" bU="1" cU="0" dU="0" aV="0" bV="0" cV="0.01" dV="0" pRange="arcLength"/></geometry>
 </planView>
 <elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
  <right><lane id="-1" type="onRamp"><link><predecessor id="-2"/><successor id="-1"/></link>
   <width sOffset="0" a="3" b="0" c="0" d="0"/><speed sOffset="0" max="no limit"/></lane></right>
 </laneSection></lanes>
</road>
<junction id="j" name="x"><connection id="0" incomingRoad="a" connectingRoad="c" contactPoint="end">
 <laneLink from="-1" to="1"/></connection></junction>
</OpenDRIVE>"#;
    // A fragment: roads b and c are not in it, so only the reader is asked.
    let od = read_xodr(text, "t").expect("parses");
    let r = &od.roads[0];
    assert_eq!(
        r.successor.as_ref().and_then(|l| l.contact_point),
        Some(ContactPoint::End)
    );
    assert_eq!(
        r.predecessor.as_ref().map(|l| l.element_type),
        Some(ElementType::Junction)
    );
    assert!((r.types[0].speed.unwrap_or(0.0) - 60.0 * 0.44704).abs() < 1e-12);
    assert!(matches!(
        r.geometries[2].kind,
        GeometryKind::ParamPoly3 {
            p_range: PRange::ArcLength,
            ..
        }
    ));
    let lane = &r.lane_sections[0].right[0];
    assert_eq!(
        (lane.predecessors.clone(), lane.successors.clone()),
        (vec![-2], vec![-1])
    );
    assert_eq!(lane.speeds[0].max, None);
    assert_eq!(lane.kind, LaneType::OnRamp);
    assert_eq!(od.junctions[0].connections[0].lane_links, vec![(-1, 1)]);
    assert_eq!(read_xodr(&to_xodr(&od), "again").expect("round trip"), od);
    let no_contact = text.replace(" contactPoint=\"end\"/></link>", "/></link>");
    assert!(parse_err(&no_contact).1.contains("contactPoint"));
    let (_, message) = parse_err(text);
    assert!(
        message.contains("road \"b\", which does not exist"),
        "{message}"
    );
}

/// Physically absurd maps are refused where they are read, naming the element's line: a lane
/// 1e9 m wide (which once hung the map sampler), a negative width (lanes silently vanished), a
/// file without roads, one whose lanes are all 0 m wide, and a 1 mm arc radius.
#[test]
fn absurd_geometry_is_refused_with_its_line() {
    let a9 = a9_text();
    let wide = a9.replacen("a=\"3.6\"", "a=\"1e9\"", 1);
    let (line, msg) = parse_err(&wide);
    assert!(
        line > 1 && msg.contains("1000000000 m wide") && msg.contains("expected 0-10 m"),
        "{msg}"
    );
    let negative = a9.replacen("a=\"3.6\"", "a=\"-3.6\"", 1);
    assert!(parse_err(&negative).1.contains("-3.6 m wide"));
    let (_, msg) = parse_err("<OpenDRIVE><header/></OpenDRIVE>");
    assert!(msg.contains("no <road>"), "{msg}");
    let mut zero = a9.clone();
    for a in ["2.6", "2.7", "3.05", "3.6", "3.7", "3.9", "4.2"] {
        zero = zero.replace(&format!("a=\"{a}\""), "a=\"0\"");
    }
    let (_, msg) = parse_err(&zero);
    assert!(msg.contains("no driving lane is 0.5 m wide"), "{msg}");
    let arc = r#"<OpenDRIVE><road id="a" length="10" junction="-1"><planView>
  <geometry s="0" x="0" y="0" hdg="0" length="10"><arc curvature="1000"/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center>
  <right><lane id="-1" type="driving"><width sOffset="0" a="3" b="0" c="0" d="0"/></lane></right>
 </laneSection></lanes></road></OpenDRIVE>"#;
    let (line, msg) = parse_err(arc);
    assert!(
        line == 2 && msg.contains("radius of 0.001 m"),
        "{line}: {msg}"
    );
    assert!(parse_xodr(&arc.replace("1000", "0.01"), "t").is_ok());
    let long = arc.replace("length=\"10\" junction", "length=\"1e9\" junction");
    assert!(parse_err(&long).1.contains("(0, 100000]"));
}

/// A road `id` of `length` m from (`x`, 0) heading +x, with `link` inside its `<link>`, and
/// driving lanes -1 and -2 (3.5 m) whose `<link>` holds `lane_link`.
fn straight(id: &str, x: f64, length: f64, link: &str, lane_link: &str) -> String {
    format!(
        r#"<road id="{id}" length="{length}" junction="-1"><link>{link}</link>
 <planView><geometry s="0" x="{x}" y="0" hdg="0" length="{length}"><line/></geometry></planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>
  <lane id="-1" type="driving"><link>{lane_link}</link><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
  <lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
 </right></laneSection></lanes>
</road>
"#
    )
}

fn document(body: &str) -> String {
    format!("<OpenDRIVE><header/>\n{body}</OpenDRIVE>")
}

/// The 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.contains(needle))
        .expect("in the text")
        + 1
}

#[test]
fn linked_road_ends_must_meet() {
    let next = r#"<successor elementType="road" elementId="b" contactPoint="start"/>"#;
    let back = r#"<predecessor elementType="road" elementId="a" contactPoint="end"/>"#;
    let joined =
        document(&(straight("a", 0.0, 100.0, next, "") + &straight("b", 100.0, 50.0, back, "")));
    parse_xodr(&joined, "t").expect("roads that meet");
    let gap =
        document(&(straight("a", 0.0, 100.0, next, "") + &straight("b", 150.0, 50.0, back, "")));
    let (line, message) = parse_err(&gap);
    assert!(message.contains("50.00 m apart"), "{message}");
    assert_eq!(line, line_of(&gap, "<successor"));
    // A road that is its own successor closes on itself only if its ends meet.
    let own = r#"<successor elementType="road" elementId="a" contactPoint="start"/>"#;
    let (_, message) = parse_err(&document(&straight("a", 0.0, 100.0, own, "")));
    assert!(message.contains("100.00 m apart"), "{message}");
}

/// Two roads joined outside a junction name each other; a link one road states and the other
/// leaves out or contradicts is refused at the link.
#[test]
fn a_road_link_the_other_road_does_not_return_is_refused() {
    let next = r#"<successor elementType="road" elementId="b" contactPoint="start"/>"#;
    let back = r#"<predecessor elementType="road" elementId="a" contactPoint="end"/>"#;
    let one_sided =
        document(&(straight("a", 0.0, 100.0, next, "") + &straight("b", 100.0, 50.0, "", "")));
    let (line, message) = parse_err(&one_sided);
    assert!(
        message.contains("road b's predecessor has no link there")
            && message.contains("name road a with contactPoint=\"end\""),
        "{message}"
    );
    assert_eq!(line, line_of(&one_sided, "<successor"));
    // Only the other road states the link: refused at its element.
    let other_only =
        document(&(straight("a", 0.0, 100.0, "", "") + &straight("b", 100.0, 50.0, back, "")));
    let (line, message) = parse_err(&other_only);
    assert!(
        message.contains("road a's successor has no link there"),
        "{message}"
    );
    assert_eq!(line, line_of(&other_only, "<predecessor"));
    // A second road c merging into b's start without a junction: b names a, not c.
    let turn: f64 = 0.3;
    let merging = straight("c", 0.0, 50.0, next, "").replace(
        r#"x="0" y="0" hdg="0""#,
        &format!(
            r#"x="{}" y="{}" hdg="{turn}""#,
            100.0 - 50.0 * turn.cos(),
            -50.0 * turn.sin()
        ),
    );
    let text = document(
        &(straight("a", 0.0, 100.0, next, "") + &straight("b", 100.0, 50.0, back, "") + &merging),
    );
    let (line, message) = parse_err(&text);
    assert!(
        message.starts_with("road c links its end to the start of road b")
            && message.contains("links it to road \"a\" at its end"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, r#"<road id="c""#), "{message}");
    parse_xodr(
        &document(&(straight("a", 0.0, 100.0, next, "") + &straight("b", 100.0, 50.0, back, ""))),
        "t",
    )
    .expect("roads that link each other");
}

#[test]
fn every_linked_lane_must_exist() {
    let next = r#"<successor elementType="road" elementId="b" contactPoint="start"/>"#;
    let back = r#"<predecessor elementType="road" elementId="a" contactPoint="end"/>"#;
    let to_missing = r#"<successor id="-3"/>"#;
    let text = document(
        &(straight("a", 0.0, 100.0, next, to_missing) + &straight("b", 100.0, 50.0, back, "")),
    );
    let (line, message) = parse_err(&text);
    assert!(message.contains("successor lane -3"), "{message}");
    assert!(message.contains("road b does not have"), "{message}");
    assert_eq!(line, line_of(&text, "<successor id=\"-3\""));
    // A lane link out of a road end that links nowhere points at nothing.
    let (_, message) = parse_err(&document(&straight("a", 0.0, 100.0, "", to_missing)));
    assert!(message.contains("has no successor link"), "{message}");
    // A junction's lane link to a lane its connecting road lacks.
    let into = r#"<successor elementType="junction" elementId="j"/>"#;
    let junction = r#"<junction id="j" name="j"><connection id="0" incomingRoad="a" connectingRoad="c" contactPoint="start">
 <laneLink from="-1" to="-5"/></connection></junction>
"#;
    let text = document(
        &(straight("a", 0.0, 100.0, into, "")
            + &straight("c", 100.0, 20.0, "", "").replace(r#"junction="-1""#, r#"junction="j""#)
            + junction),
    );
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("lane -5 of connecting road c"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<connection"));
    // The centre lane is a reference line: a link into it leads nowhere.
    let to_centre = r#"<successor id="0"/>"#;
    let text = document(
        &(straight("a", 0.0, 100.0, next, to_centre) + &straight("b", 100.0, 50.0, back, "")),
    );
    let (line, message) = parse_err(&text);
    assert!(message.contains("lane 0, the centre lane"), "{message}");
    assert_eq!(line, line_of(&text, "<successor id=\"0\""));
    let text = document(
        &(straight("a", 0.0, 100.0, into, "")
            + &straight("c", 100.0, 20.0, "", "").replace(r#"junction="-1""#, r#"junction="j""#)
            + &junction.replace(r#"to="-5""#, r#"to="0""#)),
    );
    assert!(parse_err(&text).1.contains("the centre lane"));
}

/// A junction connection leads from its incoming road to another road.
#[test]
fn a_junction_connection_from_a_road_to_itself_is_refused() {
    let into = r#"<successor elementType="junction" elementId="j"/>"#;
    let junction = r#"<junction id="j" name="j"><connection id="0" incomingRoad="a" connectingRoad="a" contactPoint="end">
 <laneLink from="-1" to="-1"/></connection></junction>
"#;
    let text = document(&(straight("a", 0.0, 100.0, into, "") + junction));
    let (line, message) = parse_err(&text);
    assert!(message.contains("connects road a to itself"), "{message}");
    assert_eq!(line, line_of(&text, "<connection"));
}

#[test]
fn a_lane_wider_than_its_bend_and_a_looping_road_are_refused() {
    // Left lanes 1 and 2 (3.5 m each) on a left bend of radius 5 m: the outer one folds.
    let tight = document(
        r#"<road id="a" length="10" junction="-1">
 <planView><geometry s="0" x="0" y="0" hdg="0" length="10"><arc curvature="0.2"/></geometry></planView>
 <lanes><laneSection s="0"><left>
  <lane id="2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
  <lane id="1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
 </left><center><lane id="0" type="none"/></center></laneSection></lanes>
</road>
"#,
    );
    let (line, message) = parse_err(&tight);
    assert!(message.contains("fold over itself"), "{message}");
    assert_eq!(line, line_of(&tight, "<lane id=\"2\""));
    // 80 m east, a 270 degree left turn of radius 20 m, 40 m south: crosses the first line.
    let arc = 1.5 * std::f64::consts::PI * 20.0;
    let looping = document(&format!(
        r#"<road id="loop" length="{}" junction="-1">
 <planView>
  <geometry s="0" x="0" y="0" hdg="0" length="80"><line/></geometry>
  <geometry s="80" x="80" y="0" hdg="0" length="{arc}"><arc curvature="0.05"/></geometry>
  <geometry s="{}" x="60" y="20" hdg="{}" length="40"><line/></geometry>
 </planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>
  <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
 </right></laneSection></lanes>
</road>
"#,
        120.0 + arc,
        80.0 + arc,
        1.5 * std::f64::consts::PI
    ));
    let (line, message) = parse_err(&looping);
    assert!(message.contains("crosses itself"), "{message}");
    assert_eq!(line, line_of(&looping, "<road id=\"loop\""));
}

#[test]
fn lane_sections_out_of_order_are_refused() {
    let a9 = a9_text();
    let at = a9.find("<laneSection").expect("a lane section");
    let end = a9[at..].find("</laneSection>").expect("its end") + at + "</laneSection>".len();
    let section = &a9[at..end];
    let later = section.replacen("s=\"0", "s=\"100", 1);
    assert_ne!(later, section, "the A9 section starts at s = 0");
    let text = format!("{}{later}{section}{}", &a9[..at], &a9[end..]);
    let (line, message) = parse_err(&text);
    assert!(message.contains("increasing s"), "{message}");
    assert!(
        line > line_of(&text, "<laneSection"),
        "the second section's line"
    );
}

#[test]
fn geometries_out_of_order_a_late_first_section_and_a_misspelt_lane_type_are_refused() {
    let road = straight("a", 0.0, 40.0, "", "");
    let two_pieces = road.replace(
        r#"<geometry s="0" x="0" y="0" hdg="0" length="40"><line/></geometry>"#,
        "<geometry s=\"20\" x=\"20\" y=\"0\" hdg=\"0\" length=\"20\"><line/></geometry>\n\
         <geometry s=\"0\" x=\"0\" y=\"0\" hdg=\"0\" length=\"20\"><line/></geometry>",
    );
    assert_ne!(two_pieces, road);
    let text = document(&two_pieces);
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("<geometry> at s = 0 comes after the previous one, at s = 20"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<geometry s=\"0\""));

    let text = document(&road.replace("<laneSection s=\"0\">", "<laneSection s=\"20\">"));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("first <laneSection> starts at s = 20"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<laneSection"));

    let text = document(&road.replacen("type=\"driving\"", "type=\"drivng\"", 1));
    let (line, message) = parse_err(&text);
    assert!(message.contains("unknown lane type `drivng`"), "{message}");
    assert_eq!(line, line_of(&text, "drivng"));
}

#[test]
fn misspelt_enumerations_and_missing_structure_are_refused_with_their_line() {
    let road = straight("a", 0.0, 40.0, "", "");
    let with_mark = road.replace(
        "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/></lane>\n  <lane id=\"-2\"",
        "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/>\
         <roadMark sOffset=\"0\" type=\"broken\" color=\"white\"/></lane>\n  <lane id=\"-2\"",
    );
    assert_ne!(with_mark, road);
    parse_xodr(&document(&with_mark), "test.xodr").expect("a valid road mark");
    let cases: [(String, &str, &str); 8] = [
        (
            road.replacen("junction=\"-1\"", "junction=\"-1\" rule=\"RTH\"", 1),
            "`rule` is `RTH`",
            "rule=",
        ),
        (
            road.replacen("junction=\"-1\"", "junction=\"j9\"", 1),
            "junction `j9`",
            "junction=\"j9\"",
        ),
        (
            road.replacen("id=\"a\"", "id=\"\"", 1),
            "`id` is empty",
            "<road",
        ),
        (
            with_mark.replace("type=\"broken\"", "type=\"brokn\""),
            "`type` is `brokn`",
            "brokn",
        ),
        (
            with_mark.replace("color=\"white\"", "color=\"whte\""),
            "`color` is `whte`",
            "whte",
        ),
        (
            road.replacen("type=\"driving\"", "type=\"driving\" level=\"maybe\"", 1),
            "`level` is `maybe`",
            "maybe",
        ),
        (
            road.replace("<center><lane id=\"0\" type=\"none\"/></center>", ""),
            "no <center> lane",
            "<laneSection",
        ),
        (
            road.replace(
                "<lanes>",
                "<lanes><laneOffset s=\"20\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>\n\
                 <laneOffset s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>",
            ),
            "<laneOffset> at s = 0 comes after the previous one",
            "<laneOffset s=\"0\"",
        ),
    ];
    for (body, expected, at) in cases {
        let text = document(&body);
        let (line, message) = parse_err(&text);
        assert!(message.contains(expected), "{expected}: {message}");
        assert_eq!(line, line_of(&text, at), "{expected}: {message}");
    }
    let typed = road.replacen("<link>", "<type s=\"0\" type=\"motorwy\"/><link>", 1);
    let sided = road.replacen(
        "<laneSection s=\"0\">",
        "<laneSection s=\"0\" singleSide=\"maybe\">",
        1,
    );
    for (text, expected, at) in [
        (document(&typed), "`type` is `motorwy`", "motorwy"),
        (document(&sided), "`singleSide` is `maybe`", "singleSide"),
        (
            document(&road).replace("<header/>", "<header revMajor=\"2\"/>"),
            "`revMajor` is `2`",
            "<header",
        ),
        (
            document(&road.replacen(
                "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/>",
                "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/>\
                 <width sOffset=\"60\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/>",
                1,
            )),
            "<width> at sOffset=60, past the section's end",
            "<lanes>",
        ),
    ] {
        let (line, message) = parse_err(&text);
        assert!(message.contains(expected), "{expected}: {message}");
        assert_eq!(line, line_of(&text, at), "{expected}: {message}");
    }
}

#[test]
fn lane_records_out_of_order_are_refused() {
    let road = |records: &str| {
        document(&format!(
            r#"<road id="a" length="200" junction="-1">
 <planView>
  <geometry s="0" x="0" y="0" hdg="0" length="200"><line/></geometry>
 </planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>
  <lane id="-1" type="driving">
{records}
  </lane>
 </right></laneSection></lanes>
</road>
"#
        ))
    };
    let width =
        |s: u32, a: f64| format!("<width sOffset=\"{s}\" a=\"{a}\" b=\"0\" c=\"0\" d=\"0\"/>\n");
    let mark = |s: u32| format!("<roadMark sOffset=\"{s}\" type=\"solid\"/>\n");
    let speed = |s: u32| format!("<speed sOffset=\"{s}\" max=\"30\"/>\n");
    parse_xodr(&road(&(width(0, 3.0) + &width(50, 3.25))), "t").expect("in order");
    for (records, tag) in [
        (width(50, 3.25) + &width(0, 3.0), "width"),
        (width(0, 3.25) + &width(0, 3.0), "width"),
        (width(0, 3.5) + &mark(80) + &mark(10), "roadMark"),
        (width(0, 3.5) + &speed(20) + &speed(20), "speed"),
    ] {
        let text = road(&records);
        let (line, message) = parse_err(&text);
        assert!(message.contains(&format!("<{tag}>")), "{message}");
        assert!(message.contains("increasing sOffset"), "{message}");
        assert!(
            line > line_of(&text, "<lane id=\"-1\""),
            "{records}: line {line}"
        );
    }
}

#[test]
fn a_reference_line_with_a_jump_or_a_kink_is_refused() {
    let road = |x2: f64, hdg2: f64| {
        document(&format!(
            r#"<road id="a" length="200" junction="-1">
 <planView>
  <geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry>
  <geometry s="100" x="{x2}" y="0" hdg="{hdg2}" length="100"><line/></geometry>
 </planView>
 <lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>
  <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
 </right></laneSection></lanes>
</road>
"#
        ))
    };
    parse_xodr(&road(100.0, 0.0), "t").expect("a continuous line");
    for (text, what) in [
        (road(300.0, 0.0), "200.000 m"),
        (road(100.0, std::f64::consts::FRAC_PI_2), "1.5708 rad"),
    ] {
        let (line, message) = parse_err(&text);
        assert!(
            message.contains(what) && message.contains("jumps or kinks"),
            "{message}"
        );
        assert_eq!(line, line_of(&text, "<geometry s=\"100\""));
    }
}

#[test]
fn linked_lanes_must_join_edge_to_edge() {
    let next = r#"<successor elementType="road" elementId="b" contactPoint="start"/>"#;
    let back = r#"<predecessor elementType="road" elementId="a" contactPoint="end"/>"#;
    let lane_next = r#"<successor id="-1"/>"#;
    let joined = document(
        &(straight("a", 0.0, 100.0, next, lane_next) + &straight("b", 100.0, 50.0, back, "")),
    );
    parse_xodr(&joined, "t").expect("lanes of one width");
    // Road b's lanes 2 m wide: lane -1's outer edge jumps 1.5 m at the link.
    let narrow = straight("b", 100.0, 50.0, back, "").replace("a=\"3.5\"", "a=\"2.0\"");
    let text = document(&(straight("a", 0.0, 100.0, next, lane_next) + &narrow));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("edges 1.50 m apart") && message.contains("lane -1 of road a"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<lane id=\"-1\""));
    // Without lane links the lanes continue into those of the same side of traffic: they
    // must meet too.
    let unlinked = document(&(straight("a", 0.0, 100.0, next, "") + &narrow));
    let (_, message) = parse_err(&unlinked);
    assert!(message.contains("edges 1.50 m apart"), "{message}");
    parse_xodr(
        &document(&(straight("a", 0.0, 100.0, next, "") + &straight("b", 100.0, 50.0, back, ""))),
        "t",
    )
    .expect("same widths, no lane links");
}

#[test]
fn a_road_id_given_twice_is_named() {
    let text = document(&(straight("a", 0.0, 100.0, "", "") + &straight("a", 0.0, 50.0, "", "")));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("road id \"a\" is given to 2 roads"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<road id=\"a\""));
}

#[test]
fn a_param_poly3_whose_curve_disagrees_with_its_length_is_refused() {
    let road = |u: &str| {
        straight("a", 0.0, 100.0, "", "").replace(
            "<line/>",
            &format!(r#"<paramPoly3 aU="0" bU="{u}" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0" pRange="normalized"/>"#),
        )
    };
    parse_xodr(&document(&road("100")), "t").expect("a 100 m curve of length 100");
    let text = document(&road("1"));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("1.00 m long") && message.contains("`length` 100 m"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<paramPoly3"));
}

#[test]
fn a_param_poly3_drawn_backwards_is_refused() {
    let road = |u: &str| {
        straight("a", 0.0, 100.0, "", "").replace(
            "<line/>",
            &format!(r#"<paramPoly3 aU="0" bU="{u}" cU="0" dU="0" aV="0" bV="0" cV="0" dV="0" pRange="normalized"/>"#),
        )
    };
    parse_xodr(&document(&road("100")), "t").expect("a curve along its heading");
    let text = document(&road("-100"));
    let (line, message) = parse_err(&text);
    assert!(message.contains("backwards"), "{message}");
    assert_eq!(line, line_of(&text, "<paramPoly3"));
}

/// Linked roads carry traffic on: a successor drawn the other way round is refused, while two
/// roads joined end to end (meeting head-on, as the contact point says) pass.
#[test]
fn a_link_that_reverses_the_direction_of_travel_is_refused() {
    let reversed = |road: String| road.replace(r#"hdg="0""#, r#"hdg="3.141592653589793""#);
    let next = |contact: &str| {
        format!(r#"<successor elementType="road" elementId="b" contactPoint="{contact}"/>"#)
    };
    let back = r#"<successor elementType="road" elementId="a" contactPoint="end"/>"#;
    let head_on = document(
        &(straight("a", 0.0, 100.0, &next("end"), "")
            + &reversed(straight("b", 150.0, 50.0, back, ""))),
    );
    parse_xodr(&head_on, "t").expect("two roads joined end to end");
    let text = document(
        &(straight("a", 0.0, 100.0, &next("start"), "")
            + &reversed(straight("b", 100.0, 50.0, "", ""))),
    );
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("turn by 3.14 rad") && message.contains("road b"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<successor"));
}

#[test]
fn a_junction_without_connections_is_refused() {
    let into = r#"<successor elementType="junction" elementId="j"/>"#;
    let text =
        document(&(straight("a", 0.0, 100.0, into, "") + "<junction id=\"j\" name=\"x\"/>\n"));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("junction j has no <connection>") && message.contains("roads a"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<junction"));
}

#[test]
fn a_road_given_twice_under_two_ids_is_refused() {
    let text = document(&(straight("a", 0.0, 100.0, "", "") + &straight("b", 20.0, 50.0, "", "")));
    let (line, message) = parse_err(&text);
    assert!(message.contains("road b lies on road a"), "{message}");
    assert_eq!(line, line_of(&text, "<road id=\"b\""));
    // The same line the other way (a carriageway for the other direction) is another road.
    let other_way =
        straight("b", 70.0, 50.0, "", "").replace(r#"hdg="0""#, r#"hdg="3.141592653589793""#);
    parse_xodr(
        &document(&(straight("a", 0.0, 100.0, "", "") + &other_way)),
        "t",
    )
    .expect("two directions");
    // But that line with its lanes on its left lies on road a's lanes: the same carriageway.
    let overlay = other_way
        .replace("<right>", "<left>")
        .replace("</right>", "</left>")
        .replace(r#"lane id="-"#, r#"lane id=""#);
    let text = document(&(straight("a", 0.0, 100.0, "", "") + &overlay));
    let (line, message) = parse_err(&text);
    assert!(
        message.contains("road b lies on road a") && message.contains("the opposite way"),
        "{message}"
    );
    assert_eq!(line, line_of(&text, "<road id=\"b\""));
}

/// A road over part of another, or beside it closer than its lanes are wide, puts lanes
/// through lanes; roads that only touch, side by side or end to end, do not.
#[test]
fn a_road_over_part_of_another_is_refused() {
    let shifted = |road: String, y: f64| road.replace(r#"y="0""#, &format!(r#"y="{y}""#));
    for other in [
        straight("b", 50.0, 100.0, "", ""),
        shifted(straight("b", 0.0, 100.0, "", ""), -1.0),
        shifted(straight("b", 0.0, 100.0, "", ""), -0.2),
    ] {
        let text = document(&(straight("a", 0.0, 100.0, "", "") + &other));
        let (line, message) = parse_err(&text);
        assert!(message.contains("road b overlaps road a"), "{message}");
        assert_eq!(line, line_of(&text, "<road id=\"b\""));
    }
    for beside in [
        shifted(straight("b", 0.0, 100.0, "", ""), -7.0),
        straight("b", 100.0, 100.0, "", ""),
    ] {
        parse_xodr(
            &document(&(straight("a", 0.0, 100.0, "", "") + &beside)),
            "t",
        )
        .expect("roads that only touch");
    }
}

/// A spiral winding inwards never crosses its own reference line, but with loops nested closer
/// than the road is wide its lanes lie over each other.
#[test]
fn a_spiral_whose_loops_overlap_is_refused() {
    // Curvature 0.04 -> 0.05 1/m over 700 m: about five loops of 20-25 m radius, each within
    // a metre of the last, under 7 m of lanes.
    let spiral = straight("a", 0.0, 700.0, "", "")
        .replace("<line/>", r#"<spiral curvStart="0.04" curvEnd="0.05"/>"#);
    let text = document(&spiral);
    let (line, message) = parse_err(&text);
    assert!(message.contains("lie over its lanes"), "{message}");
    assert_eq!(line, line_of(&text, "<road id=\"a\""));
    // One loop of the same spiral folds nothing.
    let one_loop = straight("a", 0.0, 140.0, "", "")
        .replace("<line/>", r#"<spiral curvStart="0.04" curvEnd="0.0414"/>"#);
    parse_xodr(&document(&one_loop), "t").expect("one loop");
}

/// A carriageway that steps sideways at once: a laneOffset record, a width record within a
/// lane section, or a lane linked across sections starting away from where the last ended.
#[test]
fn lane_edges_that_jump_along_a_road_are_refused() {
    let road = |offsets: &str, right: &str, second: &str| {
        document(&format!(
            r#"<road id="a" length="200" junction="-1">
 <planView>
  <geometry s="0" x="0" y="0" hdg="0" length="200"><line/></geometry>
 </planView>
 <lanes>
{offsets}
 <laneSection s="0"><center><lane id="0" type="none"/></center><right>
{right}
 </right></laneSection>
{second}
 </lanes>
</road>
"#
        ))
    };
    let offset =
        |s: u32, a: f64| format!("<laneOffset s=\"{s}\" a=\"{a}\" b=\"0\" c=\"0\" d=\"0\"/>\n");
    let lane = |widths: &str, link: &str| {
        format!("<lane id=\"-1\" type=\"driving\"><link>{link}</link>{widths}</lane>")
    };
    let width =
        |s: u32, a: f64| format!("<width sOffset=\"{s}\" a=\"{a}\" b=\"0\" c=\"0\" d=\"0\"/>");
    let section = |a: f64| {
        format!(
            r#"<laneSection s="100"><center><lane id="0" type="none"/></center><right>
<lane id="-1" type="driving">{}</lane>
</right></laneSection>"#,
            width(0, a)
        )
    };
    let linked = lane(&width(0, 3.5), r#"<successor id="-1"/>"#);
    // Continuous versions of each: a small rounding step, an offset ramp, matching sections.
    let ramp = "<laneOffset s=\"0\" a=\"0\" b=\"0.01\" c=\"0\" d=\"0\"/>\n".to_string()
        + &offset(100, 1.2);
    parse_xodr(
        &road(&ramp, &lane(&(width(0, 3.5) + &width(50, 3.7)), ""), ""),
        "t",
    )
    .expect("continuous edges");
    parse_xodr(&road("", &linked, &section(3.6)), "t").expect("sections that meet");
    // Without a link, a lane continues into the lane of the same id.
    let unlinked = lane(&width(0, 3.5), "");
    let text = road("", &unlinked, &section(9.5));
    let (line, message) = parse_err(&text);
    assert!(message.contains("6.00 m apart"), "{message}");
    assert_eq!(line, line_of(&text, "<laneSection s=\"100\""));
    for (text, needle, what) in [
        (
            road(
                &(offset(0, 0.0) + &offset(100, 30.0)),
                &lane(&width(0, 3.5), ""),
                "",
            ),
            "<laneOffset s=\"100\"",
            "30.00 m sideways",
        ),
        (
            road("", &lane(&(width(0, 3.5) + &width(50, 9.0)), ""), ""),
            "sOffset=\"50\"",
            "by 5.50 m",
        ),
        (
            road("", &linked, &section(2.0)),
            "<laneSection s=\"100\"",
            "lane -1, which continues it",
        ),
    ] {
        let (line, message) = parse_err(&text);
        assert!(message.contains(what), "{message}");
        assert_eq!(line, line_of(&text, needle), "{message}");
    }
}

/// A junction and its roads agree on who belongs to it: connection ids once, connecting roads
/// marked as the junction's, incoming roads linked to it.
#[test]
fn a_junction_and_its_roads_must_agree_on_membership() {
    let merge = include_str!("../../fuzz/seeds/opendrive/on_ramp_merge.xodr");
    parse_xodr(merge, "t").expect("the shipped merge");
    let twice = merge.replacen(r#"<connection id="1""#, r#"<connection id="0""#, 1);
    let (line, message) = parse_err(&twice);
    assert!(
        message.contains("gives connection id \"0\" to more than one connection"),
        "{message}"
    );
    assert_eq!(line, line_of(&twice, r#"<connection id="0""#));
    let outside = merge.replace(
        r#"<road id="11" name="rtr road 11" length="5" junction="100""#,
        r#"<road id="11" name="rtr road 11" length="5" junction="-1""#,
    );
    let (_, message) = parse_err(&outside);
    assert!(
        message.contains("names road 11 as a connecting road, but the road says junction=\"-1\""),
        "{message}"
    );
    let unlinked = merge.replacen(
        r#"<successor elementType="junction" elementId="100"/>"#,
        "",
        1,
    );
    let (_, message) = parse_err(&unlinked);
    assert!(
        message.contains(
            "names road 1 as an incoming road, but the road links to the junction at neither end"
        ),
        "{message}"
    );
}

/// `cases` of (document, part of the message, text on the line to blame): each refused.
fn assert_refused(cases: &[(String, &str, &str)]) {
    for (text, expected, at) in cases {
        let (line, message) = parse_err(text);
        assert!(message.contains(expected), "{expected}: {message}");
        assert_eq!(line, line_of(text, at), "{expected}: {message}");
    }
}

/// A road ("a", 40 m) whose lane -1 has a road mark and a speed record.
fn marked_road() -> String {
    straight("a", 0.0, 40.0, "", "").replacen(
        "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/></lane>",
        "<width sOffset=\"0\" a=\"3.5\" b=\"0\" c=\"0\" d=\"0\"/>\n  \
         <roadMark sOffset=\"0\" type=\"broken\" color=\"white\" width=\"0.12\"/>\n  \
         <speed sOffset=\"0\" max=\"30\"/></lane>",
        1,
    )
}

#[test]
fn names_opendrive_does_not_define_are_refused_with_their_line() {
    let road = marked_road();
    // The standard's elements rtr does not read are skipped, subtree and all.
    let rich = document(
        &road
            .replacen(
                "<planView>",
                "<userData code=\"x\"><anything at=\"all\"/></userData>\
                 <elevationProfile><elevation s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/></elevationProfile>\
                 <objects><object id=\"1\" s=\"0\" t=\"0\"/></objects><signals/>\n <planView>",
                1,
            )
            .replacen(
                "width=\"0.12\"/>",
                "width=\"0.12\"><type name=\"x\" width=\"0.1\"><line length=\"3\" space=\"6\" \
                 tOffset=\"0\" sOffset=\"0\"/></type></roadMark><material sOffset=\"0\" \
                 friction=\"1\"/><access sOffset=\"0\" rule=\"allow\"/><height sOffset=\"0\" \
                 inner=\"0\" outer=\"0\"/>",
                1,
            )
            .replacen("<line/>", "<line/><userData/>", 1),
    )
    .replace(
        "<OpenDRIVE>",
        "<OpenDRIVE xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" \
         xsi:noNamespaceSchemaLocation=\"OpenDRIVE_1.6.xsd\">",
    );
    parse_xodr(&rich, "t").expect("standard elements rtr does not read");
    let lane_children = "link, border, width, roadMark, material, visibility, speed, access, \
                         height, rule, userData, include, dataQuality";
    assert_refused(&[
        (
            document(&road.replace("<roadMark", "<roadmark")),
            "<lane> has child <roadmark>, which OpenDRIVE does not define in <lane> (did you \
             mean `roadMark`?); expected one of link",
            "<roadmark",
        ),
        (
            document(&road.replacen(
                "<speed",
                "<widht sOffset=\"20\" a=\"1\" b=\"0\" c=\"0\" d=\"0\"/>\n  <speed",
                1,
            )),
            lane_children,
            "<widht",
        ),
        (
            document(&road.replacen("d=\"0\"/>", "d=\"0\" e=\"5\"/>", 1)),
            "<width> has attribute `e`, which OpenDRIVE does not define for <width>; expected \
             one of sOffset, a, b, c, d",
            "e=\"5\"",
        ),
        (
            document(&road.replacen("<line/>", "<arc curvature=\"0.001\" radius=\"1000\"/>", 1)),
            "<arc> has attribute `radius`",
            "radius=",
        ),
        (
            document(&road.replacen("type=\"driving\"", "type=\"driving\" widht=\"3\"", 1)),
            "<lane> has attribute `widht`",
            "widht=",
        ),
        (
            document(&road.replacen("color=\"white\"", "colour=\"yellow\"", 1)),
            "<roadMark> has attribute `colour`",
            "colour=",
        ),
        (
            document(&road.replacen("<planView>", "<planVeiw/>\n <planView>", 1)),
            "<road> has child <planVeiw>",
            "<planVeiw",
        ),
        (
            document(&road.replacen("<lanes>", "<t_road_extra/>\n <lanes>", 1)),
            "<road> has child <t_road_extra>",
            "<t_road_extra",
        ),
    ]);
}

#[test]
fn lane_records_before_their_section_or_past_its_end_are_refused() {
    let road = marked_road();
    let typed = |s: &str| {
        document(&road.replacen(
            "<link>",
            &format!("<type s=\"{s}\" type=\"town\"/>\n <link>"),
            1,
        ))
    };
    parse_xodr(&typed("10"), "t").expect("a type on the road");
    assert_refused(&[
        (
            document(&road.replacen("<width sOffset=\"0\"", "<width sOffset=\"-5\"", 1)),
            "<width> attribute `sOffset` is -5; expected metres >= 0 from the lane section start",
            "sOffset=\"-5\"",
        ),
        (
            document(&road.replacen("<roadMark sOffset=\"0\"", "<roadMark sOffset=\"-50\"", 1)),
            "<roadMark> attribute `sOffset` is -50; expected metres >= 0",
            "sOffset=\"-50\"",
        ),
        (
            document(&road.replacen("<speed sOffset=\"0\"", "<speed sOffset=\"-1\"", 1)),
            "<speed> attribute `sOffset` is -1; expected metres >= 0",
            "sOffset=\"-1\"",
        ),
        (
            document(&road.replacen(
                "<speed sOffset=\"0\" max=\"30\"/>",
                "<speed sOffset=\"0\" max=\"30\"/><speed sOffset=\"900\" max=\"20\"/>",
                1,
            )),
            "has a <speed> at sOffset=900, past the section's end (40 m long)",
            "sOffset=\"900\"",
        ),
        (
            typed("950"),
            "road a: <type> attribute `s` is 950; expected metres in [0, 40]",
            "s=\"950\"",
        ),
        (
            typed("-20"),
            "road a: <type> attribute `s` is -20",
            "s=\"-20\"",
        ),
    ]);
}

#[test]
fn nonsense_road_mark_widths_and_revisions_are_refused() {
    let road = marked_road();
    assert_refused(&[
        (
            document(&road.replacen("width=\"0.12\"", "width=\"-3\"", 1)),
            "<roadMark> attribute `width` is -3 m; expected a line 0-1 m wide",
            "width=\"-3\"",
        ),
        (
            document(&road.replacen("width=\"0.12\"", "width=\"50\"", 1)),
            "<roadMark> attribute `width` is 50 m",
            "width=\"50\"",
        ),
        (
            document(&road).replace("<header/>", "<header revMajor=\"1\" revMinor=\"99\"/>"),
            "`revMinor` is `99`; expected one of 0, 1, 2, 3, 4, 5, 6, 7, 8",
            "<header",
        ),
    ]);
    for minor in ["4", "6", "8"] {
        let text = document(&road).replace(
            "<header/>",
            &format!("<header revMajor=\"1\" revMinor=\"{minor}\"/>"),
        );
        parse_xodr(&text, "t").expect("a published revision");
    }
}

#[test]
fn a_driving_lane_of_no_width_is_refused_but_one_that_opens_passes() {
    let road = straight("a", 0.0, 40.0, "", "");
    let lane_2 = |width: &str| {
        document(&road.replacen(
            "<lane id=\"-2\" type=\"driving\"><width sOffset=\"0\" a=\"3.5\" b=\"0\"",
            &format!("<lane id=\"-2\" type=\"driving\"><width sOffset=\"0\" {width}"),
            1,
        ))
    };
    let opening = lane_2("a=\"0\" b=\"0.0875\"");
    assert_ne!(opening, document(&road));
    parse_xodr(&opening, "t").expect("a lane that opens");
    parse_xodr(&lane_2("a=\"3.5\" b=\"-0.0875\""), "t").expect("a lane that closes");
    let vanished = lane_2("a=\"0\" b=\"0\"");
    assert_refused(&[(
        vanished.clone(),
        "road a: lane -2 (driving) of the laneSection at s=0 is 0 m wide along the whole section",
        "<lane id=\"-2\"",
    )]);
    // A huge value is written as a number a reader can take in.
    let (_, message) = parse_err(&lane_2("a=\"1e300\" b=\"0\""));
    assert!(message.contains("is 1e300 m wide"), "{message}");
}

#[test]
fn the_shipped_maps_and_what_the_writer_writes_still_load() {
    for (name, text) in [
        (
            "curve",
            include_str!("../../fuzz/seeds/opendrive/curve.xodr"),
        ),
        (
            "on_ramp_merge",
            include_str!("../../fuzz/seeds/opendrive/on_ramp_merge.xodr"),
        ),
    ] {
        let od = parse_xodr(text, name).expect("a shipped seed loads");
        parse_xodr(&to_xodr(&od), name).expect("written again, it loads");
    }
    parse_xodr(&a9_text(), "a9").expect("the A9 map loads");
}
