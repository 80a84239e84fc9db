//! Chunk data features and the GigE Vision transport layer features.

use super::*;

/// The chunk features, in the chunks' order ([`ChunkKind::chunk`]).
pub(super) fn chunk_features() -> impl Iterator<Item = &'static str> {
    ChunkKind::ALL
        .into_iter()
        .flat_map(|k| k.chunk().features.iter().map(|f| f.name))
}

pub(super) fn chunks(x: &mut X) {
    x.boolean(
        "ChunkModeActive",
        "Appends the enabled chunks to every image.",
        false,
        true,
        "ChunkModeActiveReg",
    );
    x.int_reg("ChunkModeActiveReg", addr::CHUNK_MODE_ACTIVE, 4, Access::Rw);
    let entries: Vec<(&str, u32, &str)> = ChunkKind::ALL
        .iter()
        .map(|k| (k.name(), *k as u32, "A chunk."))
        .collect();
    x.enumeration(
        "ChunkSelector",
        "The chunk ChunkEnable applies to.",
        false,
        "ChunkSelectorReg",
        &entries,
    );
    x.int_reg("ChunkSelectorReg", addr::CHUNK_SELECTOR, 4, Access::Rw);
    x.boolean(
        "ChunkEnable",
        "Whether the selected chunk is sent.",
        false,
        true,
        "ChunkEnableReg",
    );
    x.register(
        "IntReg",
        "ChunkEnableReg",
        addr::CHUNK_ENABLE,
        4,
        Access::Rw,
        "Device",
        Some("ChunkSelectorReg"),
        &[("Sign", "Unsigned"), ("Endianess", "BigEndian")],
    );
    for k in ChunkKind::ALL {
        x.port(&format!("Chunk{}Port", k.name()), Some(k.id()));
    }
    for k in ChunkKind::ALL {
        let c = k.chunk();
        let port = format!("Chunk{}Port", k.name());
        for (offset, f) in c.layout() {
            chunk_feature(x, c.sfnc, &port, offset, f);
        }
    }
}

/// The node of a chunk feature at byte `offset` of the chunk's data (behind `port`).
fn chunk_feature(x: &mut X, sfnc: bool, port: &str, offset: usize, f: &ChunkFeature) {
    let int_tail: &[(&str, &str)] = &[("Sign", "Unsigned"), ("Endianess", "BigEndian")];
    let (kind, tail): (&str, &[(&str, &str)]) = match f.field {
        ChunkField::F64(_) => ("FloatReg", &[("Endianess", "BigEndian")]),
        ChunkField::U64(_) | ChunkField::U32(_) => ("IntReg", int_tail),
        ChunkField::PixelFormat(_) => {
            // an enumeration of the formats, on a register of the chunk
            let entries: Vec<(&str, u32, &str)> = GevPixelFormat::ALL
                .iter()
                .map(|g| (g.name(), g.code(), "A pixel format."))
                .collect();
            let reg = format!("{}Reg", f.name);
            x.enumeration(f.name, &f.tip(), false, &reg, &entries);
            x.register(
                "IntReg",
                &reg,
                offset as u32,
                f.field.bytes() as u32,
                Access::Ro,
                port,
                None,
                int_tail,
            );
            return;
        }
    };
    x.open(kind, f.name, sfnc);
    x.head(&f.tip(), false);
    x.el(2, "Address", &format!("0x{offset:X}"));
    x.el(2, "Length", &f.field.bytes().to_string());
    x.el(2, "AccessMode", "RO");
    x.el(2, "pPort", port);
    x.el(2, "Cachable", "NoCache");
    for (a, b) in tail {
        x.el(2, a, b);
    }
    x.close(kind);
}

pub(super) fn transport(x: &mut X) {
    x.integer(
        "PayloadSize",
        "Bytes of one block (image and chunks).",
        false,
        false,
        "PayloadSizeReg",
        &[],
        Some("B"),
        None,
    );
    x.int_reg("PayloadSizeReg", addr::PAYLOAD_SIZE, 4, Access::Ro);
    x.integer(
        "GevCurrentIPAddress",
        "Address of the device.",
        true,
        false,
        "CurrentIPReg",
        &[],
        None,
        Some("IPV4Address"),
    );
    x.int_reg("CurrentIPReg", addr::CURRENT_IP, 4, Access::Ro);
    x.integer(
        "GevMACAddress",
        "MAC address.",
        true,
        false,
        "MACReg",
        &[],
        None,
        Some("MACAddress"),
    );
    x.int_reg("MACReg", addr::MAC_HIGH, 8, Access::Ro);
    x.integer(
        "GevStreamChannelCount",
        "Stream channels.",
        true,
        false,
        "StreamChannelsReg",
        &[],
        None,
        None,
    );
    x.int_reg("StreamChannelsReg", addr::STREAM_CHANNELS, 4, Access::Ro);
    x.integer(
        "GevHeartbeatTimeout",
        "Control is released when the controlling application is silent this long.",
        true,
        false,
        "HeartbeatReg",
        &[
            ("Min", registers::HEARTBEAT_MIN_MS.to_string()),
            ("Max", registers::HEARTBEAT_MAX_MS.to_string()),
        ],
        Some("ms"),
        None,
    );
    x.int_reg("HeartbeatReg", addr::HEARTBEAT_TIMEOUT, 4, Access::Rw);
    x.integer(
        "GevTimestampTickFrequency",
        "Timestamp ticks per second.",
        true,
        false,
        "TickFrequencyReg",
        &[],
        Some("Hz"),
        None,
    );
    x.int_reg("TickFrequencyReg", addr::TICK_FREQUENCY_HIGH, 8, Access::Ro);
    x.integer(
        "GevSCPSPacketSize",
        "Stream packet size, bytes with IP and UDP headers.",
        true,
        true,
        "SCPSPacketSizeReg",
        &[
            ("Min", registers::PACKET_SIZE_MIN.to_string()),
            ("Max", registers::PACKET_SIZE_MAX.to_string()),
            ("Inc", "4".into()),
        ],
        Some("B"),
        None,
    );
    x.masked(
        "SCPSPacketSizeReg",
        addr::SCPS,
        Access::Rw,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.command(
        "GevSCPSFireTestPacket",
        "Sends one test packet of the packet size.",
        true,
        "SCPSFireTestPacketReg",
        1,
    );
    x.masked(
        "SCPSFireTestPacketReg",
        addr::SCPS,
        Access::Rw,
        &[("Bit", "0")],
    );
    x.boolean(
        "GevSCPSDoNotFragment",
        "Stream packets must not be fragmented.",
        true,
        false,
        "SCPSDoNotFragmentReg",
    );
    x.masked(
        "SCPSDoNotFragmentReg",
        addr::SCPS,
        Access::Rw,
        &[("Bit", "1")],
    );
    x.integer(
        "GevSCPD",
        "Delay between stream packets, ticks (ns).",
        true,
        false,
        "SCPDReg",
        &[
            ("Min", "0".into()),
            ("Max", registers::PACKET_DELAY_MAX.to_string()),
        ],
        None,
        None,
    );
    x.int_reg("SCPDReg", addr::SCPD, 4, Access::Rw);
    x.integer(
        "GevSCDA",
        "Stream destination address.",
        true,
        false,
        "SCDAReg",
        &[],
        None,
        Some("IPV4Address"),
    );
    x.int_reg("SCDAReg", addr::SCDA, 4, Access::Rw);
    x.integer(
        "GevSCPHostPort",
        "Stream destination port (0: closed).",
        true,
        false,
        "SCPHostPortReg",
        &[],
        None,
        None,
    );
    x.masked(
        "SCPHostPortReg",
        addr::SCP,
        Access::Rw,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.integer(
        "GevSCSP",
        "Source port of the stream packets.",
        true,
        false,
        "SCSPReg",
        &[],
        None,
        None,
    );
    x.masked(
        "SCSPReg",
        addr::SCSP,
        Access::Ro,
        &[("LSB", "31"), ("MSB", "16")],
    );
    x.integer(
        "TLParamsLocked",
        "Set by the client while it streams.",
        false,
        false,
        "TLParamsLockedReg",
        &[("Min", "0".into()), ("Max", "1".into())],
        None,
        None,
    );
    x.int_reg("TLParamsLockedReg", addr::TL_PARAMS_LOCKED, 4, Access::Rw);
}
