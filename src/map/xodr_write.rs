//! Writes [`OpenDrive`] as an OpenDRIVE 1.6 document, so procedural maps can be opened in any
//! OpenDRIVE viewer. Numbers use Rust's shortest round-trip formatting, so parsing the output
//! gives back an equal struct; speeds are written in m/s.

use std::fmt::Write;

use super::opendrive::*;

/// An OpenDRIVE map as an output: a `.xodr` file with an `<OpenDRIVE>` element.
pub const OPENDRIVE_FILE: crate::io::FileKind = crate::io::FileKind {
    name: "an OpenDRIVE map",
    extensions: &["xodr"],
    recognise: |head| {
        head.windows(b"<OpenDRIVE".len())
            .any(|w| w == b"<OpenDRIVE")
    },
};

/// Serialises a map; `parse_xodr(&to_xodr(m), ..)` returns a struct equal to `m`.
pub fn to_xodr(map: &OpenDrive) -> String {
    let mut w = String::new();
    w.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<OpenDRIVE>\n");
    w.push_str("  <header revMajor=\"1\" revMinor=\"6\" name=\"rtr\" vendor=\"rtr\"/>\n");
    for road in &map.roads {
        write_road(&mut w, road);
    }
    for j in &map.junctions {
        write_junction(&mut w, j);
    }
    w.push_str("</OpenDRIVE>\n");
    w
}

/// Escapes text for use inside a double-quoted attribute.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

fn contact(c: ContactPoint) -> &'static str {
    match c {
        ContactPoint::Start => "start",
        ContactPoint::End => "end",
    }
}

// `write!` into a String cannot fail; the results are ignored on purpose.
fn write_road(w: &mut String, r: &Road) {
    let junction = r.junction.as_deref().unwrap_or("-1");
    let _ = writeln!(
        w,
        "  <road id=\"{}\" name=\"{}\" length=\"{}\" junction=\"{}\" rule=\"RHT\">",
        esc(&r.id),
        esc(&r.name),
        r.length,
        esc(junction)
    );
    if r.predecessor.is_some() || r.successor.is_some() {
        w.push_str("    <link>\n");
        for (tag, link) in [("predecessor", &r.predecessor), ("successor", &r.successor)] {
            if let Some(l) = link {
                let kind = match l.element_type {
                    ElementType::Road => "road",
                    ElementType::Junction => "junction",
                };
                let _ = write!(
                    w,
                    "      <{tag} elementType=\"{kind}\" elementId=\"{}\"",
                    esc(&l.element_id)
                );
                if let Some(c) = l.contact_point {
                    let _ = write!(w, " contactPoint=\"{}\"", contact(c));
                }
                w.push_str("/>\n");
            }
        }
        w.push_str("    </link>\n");
    }
    for t in &r.types {
        let _ = write!(w, "    <type s=\"{}\" type=\"{}\"", t.s, esc(&t.kind));
        match t.speed {
            Some(v) => {
                let _ = writeln!(w, ">\n      <speed max=\"{v}\" unit=\"m/s\"/>\n    </type>");
            }
            None => w.push_str("/>\n"),
        }
    }
    w.push_str("    <planView>\n");
    for g in &r.geometries {
        let _ = writeln!(
            w,
            "      <geometry s=\"{}\" x=\"{}\" y=\"{}\" hdg=\"{}\" length=\"{}\">",
            g.s, g.x, g.y, g.hdg, g.length
        );
        let _ = match &g.kind {
            GeometryKind::Line => writeln!(w, "        <line/>"),
            GeometryKind::Arc { curvature } => {
                writeln!(w, "        <arc curvature=\"{curvature}\"/>")
            }
            GeometryKind::Spiral {
                curv_start,
                curv_end,
            } => writeln!(
                w,
                "        <spiral curvStart=\"{curv_start}\" curvEnd=\"{curv_end}\"/>"
            ),
            GeometryKind::Poly3 { a, b, c, d } => {
                writeln!(
                    w,
                    "        <poly3 a=\"{a}\" b=\"{b}\" c=\"{c}\" d=\"{d}\"/>"
                )
            }
            GeometryKind::ParamPoly3 { u, v, p_range } => {
                let range = match p_range {
                    PRange::ArcLength => "arcLength",
                    PRange::Normalized => "normalized",
                };
                writeln!(
                    w,
                    "        <paramPoly3 aU=\"{}\" bU=\"{}\" cU=\"{}\" dU=\"{}\" aV=\"{}\" bV=\"{}\" cV=\"{}\" dV=\"{}\" pRange=\"{range}\"/>",
                    u[0], u[1], u[2], u[3], v[0], v[1], v[2], v[3]
                )
            }
        };
        w.push_str("      </geometry>\n");
    }
    w.push_str("    </planView>\n    <lanes>\n");
    for o in &r.lane_offsets {
        let _ = writeln!(
            w,
            "      <laneOffset s=\"{}\" a=\"{}\" b=\"{}\" c=\"{}\" d=\"{}\"/>",
            o.s, o.a, o.b, o.c, o.d
        );
    }
    for sec in &r.lane_sections {
        let _ = writeln!(w, "      <laneSection s=\"{}\">", sec.s);
        // OpenDRIVE lists lanes from the leftmost (highest id) to the rightmost.
        if !sec.left.is_empty() {
            w.push_str("        <left>\n");
            for lane in sec.left.iter().rev() {
                write_lane(w, lane);
            }
            w.push_str("        </left>\n");
        }
        if let Some(c) = &sec.center {
            w.push_str("        <center>\n");
            write_lane(w, c);
            w.push_str("        </center>\n");
        }
        if !sec.right.is_empty() {
            w.push_str("        <right>\n");
            for lane in &sec.right {
                write_lane(w, lane);
            }
            w.push_str("        </right>\n");
        }
        w.push_str("      </laneSection>\n");
    }
    w.push_str("    </lanes>\n  </road>\n");
}

fn write_lane(w: &mut String, l: &Lane) {
    let _ = writeln!(
        w,
        "          <lane id=\"{}\" type=\"{}\" level=\"false\">",
        l.id,
        esc(l.kind.name())
    );
    if !l.predecessors.is_empty() || !l.successors.is_empty() {
        w.push_str("            <link>\n");
        for p in &l.predecessors {
            let _ = writeln!(w, "              <predecessor id=\"{p}\"/>");
        }
        for s in &l.successors {
            let _ = writeln!(w, "              <successor id=\"{s}\"/>");
        }
        w.push_str("            </link>\n");
    }
    for wd in &l.widths {
        let _ = writeln!(
            w,
            "            <width sOffset=\"{}\" a=\"{}\" b=\"{}\" c=\"{}\" d=\"{}\"/>",
            wd.s, wd.a, wd.b, wd.c, wd.d
        );
    }
    for m in &l.road_marks {
        let _ = write!(
            w,
            "            <roadMark sOffset=\"{}\" type=\"{}\"",
            m.s_offset,
            esc(m.kind.name())
        );
        if let Some(c) = &m.color {
            let _ = write!(w, " color=\"{}\"", esc(c));
        }
        if let Some(width) = m.width {
            let _ = write!(w, " width=\"{width}\"");
        }
        w.push_str("/>\n");
    }
    for sp in &l.speeds {
        let max = sp.max.map_or("no limit".to_string(), |v| v.to_string());
        let _ = writeln!(
            w,
            "            <speed sOffset=\"{}\" max=\"{max}\" unit=\"m/s\"/>",
            sp.s_offset
        );
    }
    w.push_str("          </lane>\n");
}

fn write_junction(w: &mut String, j: &Junction) {
    let _ = writeln!(
        w,
        "  <junction id=\"{}\" name=\"{}\">",
        esc(&j.id),
        esc(&j.name)
    );
    for c in &j.connections {
        let _ = writeln!(
            w,
            "    <connection id=\"{}\" incomingRoad=\"{}\" connectingRoad=\"{}\" contactPoint=\"{}\">",
            esc(&c.id),
            esc(&c.incoming_road),
            esc(&c.connecting_road),
            contact(c.contact_point)
        );
        for (from, to) in &c.lane_links {
            let _ = writeln!(w, "      <laneLink from=\"{from}\" to=\"{to}\"/>");
        }
        w.push_str("    </connection>\n");
    }
    w.push_str("  </junction>\n");
}
