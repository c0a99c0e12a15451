//! Where a URDF's elements are, by an XML parser: the byte span and line of every `<joint>` of
//! the robot and of its `<origin>`, so that rewriting a joint never touches a comment, a CDATA
//! section or a `<transmission>`'s `<joint>` reference. The scan also bounds the input (size,
//! nesting depth) and locates syntax errors by line.

use quick_xml::events::Event;
use quick_xml::Reader;

use crate::error::{Error, Location, Result};

/// Largest URDF read (bytes).
pub(crate) const MAX_BYTES: usize = 64 << 20;

/// Deepest element nesting read (a URDF needs 4 or 5).
pub(crate) const MAX_DEPTH: usize = 256;

/// A `<joint>` element that is a child of `<robot>`.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpan {
    /// Its `name` attribute.
    pub name: String,
    /// Bytes of the whole element (`<joint ...>` to `</joint>`, or the empty tag).
    pub span: (usize, usize),
    /// Byte right after the opening tag (where a child can be inserted).
    pub(crate) after_open: usize,
    /// Bytes of its `<origin>` child, if it has one.
    pub origin: Option<(usize, usize)>,
    /// Line of the opening tag.
    pub line: usize,
}

/// The joints of a URDF, in document order.
#[derive(Debug, Clone, PartialEq)]
pub struct Index {
    /// The robot's joints.
    pub joints: Vec<JointSpan>,
    /// Where the `</robot>` closing tag starts.
    pub(crate) robot_end: Option<usize>,
}

impl Index {
    /// The joint called `name`.
    pub fn joint(&self, name: &str) -> Option<&JointSpan> {
        self.joints.iter().find(|j| j.name == name)
    }
}

/// The line of byte `pos` in `text`.
pub(crate) fn line_at(text: &str, pos: usize) -> usize {
    text.as_bytes()[..pos.min(text.len())]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// Scans a URDF: its size and depth within bounds, well-formed, and where its joints are.
pub fn scan(text: &str, file: &str) -> Result<Index> {
    let at = |pos: usize| Location::file(file).at_line(line_at(text, pos));
    if text.len() > MAX_BYTES {
        return Err(Error::input(
            Location::file(file),
            format!(
                "{} bytes: larger than the {} MiB a URDF may be here",
                text.len(),
                MAX_BYTES >> 20
            ),
        ));
    }
    // A byte-order mark is not XML: the parser reads what follows it, and every position
    // found is moved past it, so that spans index `text` itself.
    let bom = if text.starts_with('\u{feff}') {
        '\u{feff}'.len_utf8()
    } else {
        0
    };
    let mut reader = Reader::from_str(&text[bom..]);
    reader.config_mut().check_end_names = true;
    let mut depth = 0usize;
    // The element names from the root down, and the joint being read (index into `joints`).
    let mut path: Vec<String> = Vec::new();
    let mut joints: Vec<JointSpan> = Vec::new();
    let mut open_joint: Option<usize> = None;
    let mut origin_start: Option<usize> = None;
    let mut robot_end = None;
    loop {
        let before = bom + reader.buffer_position() as usize;
        let event = reader.read_event().map_err(|e| {
            Error::input(
                at(bom + reader.error_position() as usize),
                format!("not well-formed XML: {e}"),
            )
        })?;
        let after = bom + reader.buffer_position() as usize;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let empty = matches!(event, Event::Empty(_));
                let name = String::from_utf8_lossy(e.name().as_ref()).to_string();
                if !empty {
                    depth += 1;
                    if depth > MAX_DEPTH {
                        return Err(Error::input(
                            at(before),
                            format!("elements nested deeper than {MAX_DEPTH}: not a URDF"),
                        ));
                    }
                }
                let under_robot = path.len() == 1 && path[0] == "robot";
                if name == "joint" && under_robot {
                    let joint_name = e
                        .try_get_attribute("name")
                        .ok()
                        .flatten()
                        .and_then(|a| a.unescape_value().ok().map(|v| v.to_string()))
                        .unwrap_or_default();
                    joints.push(JointSpan {
                        name: joint_name,
                        span: (before, after),
                        after_open: after,
                        origin: None,
                        line: line_at(text, before),
                    });
                    if !empty {
                        open_joint = Some(joints.len() - 1);
                    }
                } else if name == "origin" && path.len() == 2 && open_joint.is_some() {
                    if empty {
                        let j = open_joint.expect("checked");
                        joints[j].origin.get_or_insert((before, after));
                    } else {
                        origin_start = Some(before);
                    }
                }
                if !empty {
                    path.push(name);
                }
            }
            Event::End(_) => {
                let name = path.pop().unwrap_or_default();
                depth = depth.saturating_sub(1);
                if name == "robot" && path.is_empty() {
                    robot_end = Some(before);
                }
                if name == "origin" {
                    if let (Some(j), Some(s)) = (open_joint, origin_start.take()) {
                        joints[j].origin.get_or_insert((s, after));
                    }
                } else if name == "joint" && path.len() == 1 {
                    if let Some(j) = open_joint.take() {
                        joints[j].span.1 = after;
                    }
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if depth != 0 {
        return Err(Error::input(
            at(text.len()),
            "not well-formed XML: the document ends inside an element",
        ));
    }
    Ok(Index { joints, robot_end })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_are_found_past_comments_and_transmissions() {
        let text = r#"<robot name="r">
  <!-- <joint name="j1" type="fixed"><origin xyz="9 9 9"/></joint> -->
  <link name="a"/>
  <joint name="j1" type="revolute">
    <parent link="a"/><child link="b"/>
    <origin xyz="1 2 3" rpy="0 0 0"/>
  </joint>
  <transmission name="t"><joint name="j1"><hardwareInterface>x</hardwareInterface></joint></transmission>
  <joint name="j2" type="fixed"><parent link="b"/><child link="c"/></joint>
</robot>"#;
        let idx = scan(text, "r.urdf").unwrap();
        assert_eq!(idx.joints.len(), 2);
        let j1 = idx.joint("j1").unwrap();
        assert_eq!(j1.line, 4);
        let (s, e) = j1.origin.unwrap();
        assert_eq!(&text[s..e], r#"<origin xyz="1 2 3" rpy="0 0 0"/>"#);
        assert!(text[j1.span.0..j1.span.1].ends_with("</joint>"));
        assert!(idx.joint("j2").unwrap().origin.is_none());
    }

    #[test]
    fn bad_xml_is_refused_with_its_line() {
        let e = scan("<robot>\n  <joint name=\"a\">\n</robot>\n", "x.urdf")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("x.urdf:3:"), "{e}");
        let deep = "<a>".repeat(20_000) + &"</a>".repeat(20_000);
        let e = scan(&deep, "d.urdf").unwrap_err().to_string();
        assert!(e.contains("nested deeper than 256"), "{e}");
        let e = scan("<robot><link name=\"x\">", "t.urdf")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.urdf:1"), "{e}");
    }
}
