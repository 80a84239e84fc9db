//! The `metadata.yaml` of a rosbag2 bag, version 8 (read by Humble and every later release),
//! and the QoS profile psns offers for its topics.
//!
//! rosbag2 writes this file when a recording is closed; a bag directory without it is
//! unfinished (`ros2 bag reindex` rebuilds it). The same text, without the top-level key, goes
//! into the MCAP file as its `rosbag2` metadata record (`serialized_metadata`).

use std::fmt::Write;

/// rosbag2 metadata version written.
pub const VERSION: u32 = 8;

/// The QoS profile offered on every topic, in version 8's form (a YAML list in a string, enums
/// as rmw numbers): history unknown (3) and depth 0 as rosbag2 records them, reliable (1),
/// volatile (2), automatic liveliness (1), infinite deadline, lifespan and lease
/// (9223372036 s 854775807 ns). Replayed, a reliable and volatile publisher matches reliable and
/// best-effort subscribers.
pub const OFFERED_QOS_V8: &str = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  \
deadline:\n    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n    \
nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n    sec: 9223372036\n    \
nsec: 854775807\n  avoid_ros_namespace_conventions: false";

/// One topic of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Topic {
    /// Topic name, e.g. `/psns/image_raw`.
    pub name: String,
    /// Message type, e.g. `sensor_msgs/msg/Image`.
    pub msg_type: String,
    /// Messages written.
    pub count: u64,
}

/// What `metadata.yaml` says about a bag of one MCAP file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BagInfo {
    /// The MCAP file's name, relative to the bag directory.
    pub file: String,
    /// Earliest message time, ns since 1970 (0 with no messages).
    pub start_ns: u64,
    /// Latest message time, ns since 1970 (0 with no messages).
    pub end_ns: u64,
    /// Topics in the order their channels were added.
    pub topics: Vec<Topic>,
    /// `custom_data` (keys and values as written).
    pub custom_data: Vec<(String, String)>,
    /// `ros_distro`.
    pub ros_distro: String,
}

impl BagInfo {
    /// Messages on every topic.
    pub fn message_count(&self) -> u64 {
        self.topics.iter().map(|t| t.count).sum()
    }

    /// Latest minus earliest message time, as rosbag2 counts the duration.
    pub fn duration_ns(&self) -> u64 {
        self.end_ns.saturating_sub(self.start_ns)
    }

    /// The `metadata.yaml` text.
    ///
    /// ```
    /// use psns::ros2::metadata::{BagInfo, Topic};
    /// let b = BagInfo {
    ///     file: "run_0.mcap".into(),
    ///     start_ns: 10,
    ///     end_ns: 60,
    ///     topics: vec![Topic { name: "/a".into(), msg_type: "std_msgs/msg/Header".into(), count: 2 }],
    ///     custom_data: vec![],
    ///     ros_distro: String::new(),
    /// };
    /// let y = b.yaml();
    /// assert!(y.starts_with("rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n"));
    /// assert!(y.contains("\n  duration:\n    nanoseconds: 50\n"));
    /// ```
    pub fn yaml(&self) -> String {
        let mut s = String::from("rosbag2_bagfile_information:\n");
        for line in self.serialized().lines() {
            s.push_str("  ");
            s.push_str(line);
            s.push('\n');
        }
        s
    }

    /// The mapping under `rosbag2_bagfile_information` (no trailing newline), as rosbag2 stores
    /// it in the MCAP file's `rosbag2` metadata record.
    pub fn serialized(&self) -> String {
        let mut s = String::new();
        let q = yaml_string;
        // writing to a String cannot fail
        let _ = writeln!(s, "version: {VERSION}");
        s.push_str("storage_identifier: mcap\n");
        let _ = writeln!(s, "duration:\n  nanoseconds: {}", self.duration_ns());
        let _ = writeln!(
            s,
            "starting_time:\n  nanoseconds_since_epoch: {}",
            self.start_ns
        );
        let _ = writeln!(s, "message_count: {}", self.message_count());
        if self.topics.is_empty() {
            s.push_str("topics_with_message_count: []\n");
        } else {
            s.push_str("topics_with_message_count:\n");
        }
        for t in &self.topics {
            let _ = writeln!(s, "  - topic_metadata:\n      name: {}", q(&t.name));
            let _ = writeln!(s, "      type: {}", q(&t.msg_type));
            s.push_str("      serialization_format: cdr\n");
            let _ = writeln!(s, "      offered_qos_profiles: {}", q(OFFERED_QOS_V8));
            s.push_str("      type_description_hash: \"\"\n");
            let _ = writeln!(s, "    message_count: {}", t.count);
        }
        s.push_str("compression_format: \"\"\ncompression_mode: \"\"\n");
        let _ = writeln!(s, "relative_file_paths:\n  - {}", q(&self.file));
        let _ = writeln!(s, "files:\n  - path: {}", q(&self.file));
        let _ = writeln!(
            s,
            "    starting_time:\n      nanoseconds_since_epoch: {}",
            self.start_ns
        );
        let _ = writeln!(
            s,
            "    duration:\n      nanoseconds: {}",
            self.duration_ns()
        );
        let _ = writeln!(s, "    message_count: {}", self.message_count());
        if self.custom_data.is_empty() {
            s.push_str("custom_data: ~\n");
        } else {
            s.push_str("custom_data:\n");
            for (k, v) in &self.custom_data {
                let _ = writeln!(s, "  {}: {}", q(k), q(v));
            }
        }
        let _ = write!(s, "ros_distro: {}", q(&self.ros_distro));
        s
    }
}

/// A YAML double-quoted scalar: `"` and `\` escaped, control characters as `\n`, `\t` or
/// `\xNN` / `\uNNNN`.
///
/// ```
/// use psns::ros2::metadata::yaml_string;
/// assert_eq!(yaml_string("a\"b\\c\nd"), r#""a\"b\\c\nd""#);
/// ```
pub fn yaml_string(v: &str) -> String {
    let mut s = String::with_capacity(v.len() + 2);
    s.push('"');
    for c in v.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\t' => s.push_str("\\t"),
            '\r' => s.push_str("\\r"),
            c if (c as u32) < 0x20 || c == '\u{7f}' => {
                let _ = write!(s, "\\x{:02x}", c as u32);
            }
            // YAML's own line and paragraph separators and the BOM would not survive plain
            c @ ('\u{85}' | '\u{2028}' | '\u{2029}' | '\u{feff}') => {
                let _ = write!(s, "\\u{:04x}", c as u32);
            }
            c => s.push(c),
        }
    }
    s.push('"');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_bag_has_empty_lists() {
        let b = BagInfo {
            file: "b_0.mcap".into(),
            start_ns: 0,
            end_ns: 0,
            topics: vec![],
            custom_data: vec![],
            ros_distro: String::new(),
        };
        let y = b.yaml();
        assert!(y.contains("  topics_with_message_count: []\n"), "{y}");
        assert!(y.contains("  message_count: 0\n"), "{y}");
        assert!(y.ends_with("  ros_distro: \"\"\n"), "{y}");
    }

    #[test]
    fn yaml_is_indented_under_the_top_key() {
        let b = BagInfo {
            file: "b_0.mcap".into(),
            start_ns: 5,
            end_ns: 5,
            topics: vec![Topic {
                name: "/x".into(),
                msg_type: "t/msg/T".into(),
                count: 1,
            }],
            custom_data: vec![("k".into(), "{\"a\": 1}".into())],
            ros_distro: "d".into(),
        };
        let y = b.yaml();
        for l in y.lines().skip(1) {
            assert!(l.starts_with("  "), "{l:?}");
        }
        assert!(y.contains("    \"k\": \"{\\\"a\\\": 1}\"\n"), "{y}");
    }
}
