//! The chunk table ([`ChunkKind::chunk`]) against what derives from it: every chunk and each of
//! its features in the GenICam XML, at the offset and length the encoded chunk has it, and the
//! table in docs/gige.md.

use psns::gige::chunk::{self, ChunkField, ChunkKind, ChunkValues};
use psns::gige::pixel::GevPixelFormat;
use std::collections::HashMap;
use std::path::Path;

/// A node of the XML: its element kind, namespace and child elements (first of each name).
struct Node {
    kind: String,
    namespace: String,
    children: HashMap<String, String>,
}

/// The top-level nodes of the XML by name (the writer puts one element per line).
fn nodes(xml: &str) -> HashMap<String, Node> {
    let mut out = HashMap::new();
    let mut current: Option<(String, Node)> = None;
    for line in xml.lines() {
        if let Some(open) = line.strip_prefix("  <").filter(|l| !l.starts_with('/')) {
            let kind = open.split(' ').next().unwrap().to_string();
            let attr = |a: &str| {
                open.split(&format!("{a}=\""))
                    .nth(1)
                    .map(|r| r.split('"').next().unwrap().to_string())
                    .unwrap_or_default()
            };
            let node = Node {
                kind,
                namespace: attr("NameSpace"),
                children: HashMap::new(),
            };
            current = Some((attr("Name"), node));
        } else if line.starts_with("  </") {
            let (name, node) = current.take().expect("a closing tag after an opening one");
            assert!(out.insert(name.clone(), node).is_none(), "{name} twice");
        } else if let Some((_, node)) = current.as_mut() {
            let t = line.trim();
            if let Some(rest) = t.strip_prefix('<') {
                if let Some((tag, rest)) = rest.split_once('>') {
                    let tag = tag.split(' ').next().unwrap().to_string();
                    if let Some(value) = rest.strip_suffix(&format!("</{tag}>")) {
                        node.children
                            .entry(tag)
                            .or_insert_with(|| value.to_string());
                    }
                }
            }
        }
    }
    out
}

/// Values whose every field is distinct, so that a feature read at the wrong offset differs.
fn values() -> ChunkValues {
    ChunkValues {
        exposure_us: 1234.5,
        gain_db: 3.25,
        timestamp: 0x0102_0304_0506_0708,
        frame_index: 41,
        attitude_wxyz: [0.5, -0.25, 0.125, -0.0625],
        sun_azimuth_deg: 200.5,
        sun_elevation_deg: 40.75,
        region: [2, 4, 640, 480],
        pixel_format: GevPixelFormat::PolarizeMono12p.code(),
    }
}

/// Every chunk's port and each of its features are in the XML: its node, namespace, tooltip,
/// and the register at the offset and length where the encoded chunk holds the feature's value
/// (checked against the values by name, not through the table); the chunk category lists every
/// feature and no feature of the XML reads a chunk the table does not have.
#[test]
fn every_chunk_feature_is_in_the_xml_where_the_chunk_holds_it() {
    let xml = psns::gige::xml::genicam_xml();
    let nodes = nodes(&xml);
    let v = values();
    let want: HashMap<&str, f64> = [
        ("ChunkExposureTime", v.exposure_us),
        ("ChunkGain", v.gain_db),
        ("ChunkTimestamp", v.timestamp as f64),
        ("ChunkFrameIndex", v.frame_index as f64),
        ("ChunkAttitudeW", v.attitude_wxyz[0]),
        ("ChunkAttitudeX", v.attitude_wxyz[1]),
        ("ChunkAttitudeY", v.attitude_wxyz[2]),
        ("ChunkAttitudeZ", v.attitude_wxyz[3]),
        ("ChunkSunAzimuth", v.sun_azimuth_deg),
        ("ChunkSunElevation", v.sun_elevation_deg),
        ("ChunkOffsetX", v.region[0] as f64),
        ("ChunkOffsetY", v.region[1] as f64),
        ("ChunkWidth", v.region[2] as f64),
        ("ChunkHeight", v.region[3] as f64),
        ("ChunkPixelFormat", v.pixel_format as f64),
    ]
    .into();
    let category = &nodes["ChunkDataControl"];
    let listed: Vec<&str> = xml
        .split("<Category Name=\"ChunkDataControl\"")
        .nth(1)
        .unwrap()
        .split("</Category>")
        .next()
        .unwrap()
        .lines()
        .filter_map(|l| l.trim().strip_prefix("<pFeature>"))
        .map(|l| l.strip_suffix("</pFeature>").unwrap())
        .collect();
    assert_eq!(category.kind, "Category");
    let mut table_features = Vec::new();
    let mut ports = Vec::new();
    for k in ChunkKind::ALL {
        let c = k.chunk();
        assert_eq!(k.data_len(), c.data_len());
        // the chunk encoded alone: its data is what the XML's registers address
        let mut tail = Vec::new();
        chunk::append(&mut tail, 0, 1 << k as u32, &v);
        let found = chunk::chunks(&tail).unwrap();
        assert_eq!(found.len(), 2, "{k:?}");
        let (id, data) = found[0];
        assert_eq!((id, data.len()), (k.id(), k.data_len()), "{k:?}");
        let port = format!("Chunk{}Port", k.name());
        let p = nodes.get(&port).unwrap_or_else(|| panic!("no {port}"));
        assert_eq!(p.kind, "Port");
        assert_eq!(p.children["ChunkID"], format!("{:08X}", k.id()));
        ports.push(port.clone());
        assert!(
            xml.contains(&format!("<EnumEntry Name=\"{}\"", k.name())),
            "{k:?} is not a ChunkSelector entry"
        );
        let mut covered = 0;
        for (offset, f) in c.layout() {
            table_features.push(f.name);
            let node = nodes
                .get(f.name)
                .unwrap_or_else(|| panic!("{} is not in the XML", f.name));
            assert_eq!(node.children["ToolTip"], f.tip(), "{}", f.name);
            assert!(
                listed.contains(&f.name),
                "{} not in ChunkDataControl",
                f.name
            );
            let reg = match f.field {
                ChunkField::PixelFormat(_) => {
                    assert_eq!(node.kind, "Enumeration", "{}", f.name);
                    &nodes[&node.children["pValue"]]
                }
                ChunkField::F64(_) => {
                    assert_eq!(node.kind, "FloatReg", "{}", f.name);
                    node
                }
                ChunkField::U64(_) | ChunkField::U32(_) => {
                    assert_eq!(node.kind, "IntReg", "{}", f.name);
                    node
                }
            };
            let ns = if c.sfnc { "Standard" } else { "Custom" };
            assert_eq!(node.namespace, ns, "{}", f.name);
            assert_eq!(reg.children["pPort"], port, "{}", f.name);
            assert_eq!(reg.children["AccessMode"], "RO", "{}", f.name);
            assert_eq!(reg.children["Endianess"], "BigEndian", "{}", f.name);
            let at = usize::from_str_radix(reg.children["Address"].strip_prefix("0x").unwrap(), 16)
                .unwrap();
            let len: usize = reg.children["Length"].parse().unwrap();
            assert_eq!((at, len), (offset, f.field.bytes()), "{}", f.name);
            let bytes = &data[at..at + len];
            let got = match (reg.kind.as_str(), len) {
                ("FloatReg", 8) => f64::from_be_bytes(bytes.try_into().unwrap()),
                ("IntReg", 8) => u64::from_be_bytes(bytes.try_into().unwrap()) as f64,
                ("IntReg", 4) => u32::from_be_bytes(bytes.try_into().unwrap()) as f64,
                other => panic!("{}: a {other:?} register", f.name),
            };
            assert_eq!(Some(&got), want.get(f.name), "{}", f.name);
            covered += len;
        }
        assert_eq!(covered, data.len(), "{k:?}: features do not cover the data");
    }
    // every feature checked against a value, and the category lists the table's features
    let mut named: Vec<&str> = want.keys().copied().collect();
    named.sort();
    let mut sorted = table_features.clone();
    sorted.sort();
    assert_eq!(sorted, named);
    let chunk_listed: Vec<&str> = listed
        .iter()
        .copied()
        .filter(|f| !["ChunkModeActive", "ChunkSelector", "ChunkEnable"].contains(f))
        .collect();
    assert_eq!(chunk_listed, table_features);
    // no register reads a chunk port the table does not have
    for (name, n) in &nodes {
        if let Some(p) = n.children.get("pPort").filter(|p| p.starts_with("Chunk")) {
            assert!(ports.contains(p), "{name} reads {p}");
        }
    }
}

/// The chunk table in docs/gige.md, as the library's table gives it.
fn docs_table() -> String {
    let mut t = String::from(
        "| ChunkSelector | id | feature | offset | type | unit | what |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for k in ChunkKind::ALL {
        let c = k.chunk();
        for (offset, f) in c.layout() {
            t.push_str(&format!(
                "| {} | 0x{:08X} | {} | {offset} | {} | {} | {} |\n",
                k.name(),
                k.id(),
                f.name,
                f.field.type_name(),
                f.unit.unwrap_or(""),
                f.what
            ));
        }
    }
    t
}

#[test]
fn the_chunk_table_of_the_docs_is_the_library_table() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/gige.md"))
        .unwrap();
    let want = docs_table();
    assert!(
        doc.contains(&want),
        "docs/gige.md's chunk table differs from the library's; it is:\n{want}"
    );
}
