//! The DBC is the definition of the CAN layout; `pbm::can::layout` is its copy in code. This
//! test parses `can/brake_monitor.dbc` with an independent parser (`can-dbc`) and checks every
//! message and signal of the code against it, both ways.

use can_dbc::{AttributeValue, ByteOrder, Comment, Dbc, MessageId, NumericValue, ValueDescription, ValueType};
use pbm::can::layout::{self, Message};
use pbm::FaultClass;

fn dbc() -> Dbc {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/can/brake_monitor.dbc");
    let text = std::fs::read_to_string(path).expect("can/brake_monitor.dbc is readable");
    Dbc::try_from(text.as_str()).expect("can/brake_monitor.dbc parses")
}

fn num(v: NumericValue) -> f64 {
    match v {
        NumericValue::Uint(u) => u as f64,
        NumericValue::Int(i) => i as f64,
        NumericValue::Double(d) => d,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

fn code_message(id: MessageId) -> Option<&'static Message> {
    match id {
        MessageId::Extended(raw) => layout::MESSAGES.iter().find(|m| m.raw_id() == raw),
        MessageId::Standard(_) => None,
    }
}

#[test]
fn every_message_and_signal_matches_the_code() {
    let dbc = dbc();
    assert_eq!(dbc.messages.len(), layout::MESSAGES.len(), "same number of messages");
    for dm in &dbc.messages {
        let cm = code_message(dm.id).unwrap_or_else(|| panic!("DBC message {} ({:?}) not in code", dm.name, dm.id));
        assert_eq!(dm.name, cm.name);
        assert_eq!(dm.size, u64::from(cm.dlc), "{}", dm.name);
        assert_eq!(dm.transmitter.as_deref(), Some("BPM"), "{}", dm.name);
        assert_eq!(dm.signals.len(), cm.signals.len(), "{}: same number of signals", dm.name);
        for ds in &dm.signals {
            let cs = cm
                .signals
                .iter()
                .find(|s| s.name == ds.name)
                .unwrap_or_else(|| panic!("DBC signal {}.{} not in code", dm.name, ds.name));
            let what = format!("{}.{}", dm.name, ds.name);
            assert_eq!(ds.start_bit, u64::from(cs.start_bit), "{what}: start bit");
            assert_eq!(ds.size, u64::from(cs.len), "{what}: length");
            assert_eq!(ds.byte_order, ByteOrder::LittleEndian, "{what}: byte order");
            assert_eq!(ds.value_type, ValueType::Unsigned, "{what}: sign");
            assert!(close(ds.factor, cs.factor), "{what}: factor {} vs {}", ds.factor, cs.factor);
            assert!(close(ds.offset, cs.offset), "{what}: offset");
            assert!(close(num(ds.min), cs.min), "{what}: min");
            assert!(close(num(ds.max), cs.max), "{what}: max {} vs {}", num(ds.max), cs.max);
            // The declared range is exactly what the raw field can carry.
            assert!(close(cs.max, cs.max_raw() as f64 * cs.factor + cs.offset) || cs.name == "Confidence", "{what}");
            assert_eq!(ds.unit, cs.unit, "{what}: unit");
            assert_eq!(ds.receivers, ["CAB"], "{what}: receivers");
        }
    }
    // The monitor transmits nothing else: exactly two extended-id data frames.
    for m in layout::MESSAGES {
        assert!(m.raw_id() > 0x7FF, "{} uses an extended id", m.name);
    }
}

#[test]
fn value_tables_match_the_code() {
    let dbc = dbc();
    let table = |msg: &Message, sig: &str| -> Vec<(i64, String)> {
        dbc.value_descriptions
            .iter()
            .find_map(|vd| match vd {
                ValueDescription::Signal { message_id: MessageId::Extended(id), name, value_descriptions }
                    if *id == msg.raw_id() && name == sig =>
                {
                    Some(value_descriptions.iter().map(|v| (v.id, v.description.clone())).collect())
                }
                _ => None,
            })
            .unwrap_or_else(|| panic!("no VAL_ table for {}.{sig}", msg.name))
    };

    let mut diagnosis: Vec<(i64, String)> =
        FaultClass::ALL.iter().map(|c| (i64::from(*c as u8), c.label().to_string())).collect();
    diagnosis.push((i64::from(layout::DIAGNOSIS_CANNOT_DIAGNOSE), "cannot_diagnose".into()));
    assert_eq!(table(&layout::FAULT_REPORT, layout::DIAGNOSIS.name), diagnosis);

    // Codes whose label is empty are not used (no VAL_ entry).
    let labels = |l: &[&str]| -> Vec<(i64, String)> {
        l.iter().enumerate().filter(|(_, s)| !s.is_empty()).map(|(i, s)| (i as i64, s.to_string())).collect()
    };
    assert_eq!(table(&layout::FAULT_REPORT, layout::NO_DIAGNOSIS_REASON.name), labels(&layout::reason::LABELS));
    assert_eq!(table(&layout::STATUS, layout::SENSOR_HEALTH.name), labels(&layout::sensor_health::LABELS));
    assert_eq!(table(&layout::STATUS, layout::ESTIMATOR_STATE.name), labels(&layout::ESTIMATOR_STATE_LABELS));
    assert_eq!(table(&layout::FAULT_REPORT, layout::RELEASE_COMPLETED.name), labels(&["in_progress", "completed"]));
}

#[test]
fn cycle_times_and_data_ids_are_documented_in_the_dbc() {
    let dbc = dbc();
    for m in layout::MESSAGES {
        let cycle = dbc
            .attribute_values_message
            .iter()
            .find(|a| a.name == "GenMsgCycleTime" && a.message_id == MessageId::Extended(m.raw_id()))
            .map(|a| a.value.clone());
        let cycle_ms = match cycle {
            Some(AttributeValue::Uint(v)) => v as f64,
            Some(AttributeValue::Int(v)) => v as f64,
            Some(AttributeValue::Double(v)) => v,
            other => panic!("{}: GenMsgCycleTime {other:?}", m.name),
        };
        assert!(close(cycle_ms, f64::from(m.cycle_ms)), "{}", m.name);
        let comment = dbc
            .comments
            .iter()
            .find_map(|c| match c {
                Comment::Message { id, comment } if *id == MessageId::Extended(m.raw_id()) => Some(comment.clone()),
                _ => None,
            })
            .unwrap_or_default();
        assert!(comment.contains(&format!("data ID 0x{:04X}", m.data_id)), "{}: comment names the data ID", m.name);
    }
}

/// The codec converts report units (10 ms, mbar, µm) to raw values with integer constants;
/// those must mean the same as the DBC's factors and units, or cantools would show other
/// values than the display.
#[test]
fn codec_resolutions_agree_with_the_dbc_factors() {
    let dbc = dbc();
    let factor = |msg: &Message, sig: &str| -> (f64, String) {
        let m = dbc.messages.iter().find(|m| m.id == MessageId::Extended(msg.raw_id())).expect("message in DBC");
        let s = m.signals.iter().find(|s| s.name == sig).expect("signal in DBC");
        (s.factor, s.unit.clone())
    };
    let cases = [
        (&layout::FAULT_REPORT, layout::TIME_SINCE_RELEASE.name, f64::from(layout::TIME_CS_PER_LSB) * 0.01, "s"),
        (&layout::FAULT_REPORT, layout::SUPPLY_PRESSURE.name, f64::from(layout::SUPPLY_MBAR_PER_LSB) * 0.001, "bar"),
        (&layout::FAULT_REPORT, layout::LEAK_DIAMETER.name, f64::from(layout::LEAK_UM_PER_LSB) * 0.001, "mm"),
        (&layout::FAULT_REPORT, layout::CONFIDENCE.name, 1.0, "%"),
        // StatusReport::pressure_mbar is sent as is.
        (&layout::STATUS, layout::CHAMBER_PRESSURE.name, 0.001, "bar"),
    ];
    for (msg, sig, per_lsb, unit) in cases {
        let (f, u) = factor(msg, sig);
        assert!(close(f, per_lsb), "{sig}: DBC factor {f} vs codec {per_lsb}");
        assert_eq!(u, unit, "{sig}");
    }
    // Names are unique in code, so the one-way lookup above is a bijection.
    for m in layout::MESSAGES {
        for (i, a) in m.signals.iter().enumerate() {
            assert!(m.signals[i + 1..].iter().all(|b| b.name != a.name), "{} twice", a.name);
        }
    }
}

/// Vector / J1939 conventions, so CANdb++, CANoe and J1939 tools read the file as intended:
/// `BusType` CAN, `ProtocolType` J1939, `VFrameFormat` J1939PG for both 29-bit messages, and
/// `GenMsgSendType` as the standard ENUM (cyclic for the status frame,
/// cyclicIfActiveAndTriggered for the fault report: on change, and at 1 Hz while releasing).
#[test]
fn dbc_follows_vector_and_j1939_conventions() {
    use can_dbc::{AttributeDefinition, AttributeValueType};
    let dbc = dbc();
    let db_value = |name: &str| {
        dbc.attribute_values_database
            .iter()
            .find(|a| a.name == name)
            .map(|a| a.value.clone())
            .unwrap_or_else(|| panic!("no database attribute {name}"))
    };
    assert_eq!(db_value("BusType"), AttributeValue::String("CAN".into()));
    assert_eq!(db_value("ProtocolType"), AttributeValue::String("J1939".into()));
    let enum_of = |name: &str| -> Vec<String> {
        dbc.attribute_definitions
            .iter()
            .find_map(|d| match d {
                AttributeDefinition::Message(n, AttributeValueType::Enum(v)) if n == name => Some(v.clone()),
                _ => None,
            })
            .unwrap_or_else(|| panic!("{name} is no message ENUM attribute"))
    };
    let frame_formats = enum_of("VFrameFormat");
    assert_eq!(frame_formats[..4], ["StandardCAN", "ExtendedCAN", "reserved", "J1939PG"]);
    let send_types = enum_of("GenMsgSendType");
    assert_eq!(
        send_types,
        ["cyclic", "triggered", "cyclicIfActive", "cyclicAndTriggered", "cyclicIfActiveAndTriggered", "none"]
    );
    let msg_value = |name: &str, m: &Message| -> usize {
        match dbc
            .attribute_values_message
            .iter()
            .find(|a| a.name == name && a.message_id == MessageId::Extended(m.raw_id()))
            .map(|a| a.value.clone())
        {
            Some(AttributeValue::Uint(v)) => v as usize,
            Some(AttributeValue::Int(v)) => v as usize,
            other => panic!("{}: {name} {other:?}", m.name),
        }
    };
    for m in layout::MESSAGES {
        assert_eq!(frame_formats[msg_value("VFrameFormat", &m)], "J1939PG", "{}", m.name);
    }
    assert_eq!(send_types[msg_value("GenMsgSendType", &layout::STATUS)], "cyclic");
    assert_eq!(send_types[msg_value("GenMsgSendType", &layout::FAULT_REPORT)], "cyclicIfActiveAndTriggered");
    // Confidence is a clean percentage: 0..100 %, one percent per bit.
    let conf = &layout::CONFIDENCE;
    assert_eq!((conf.factor, conf.offset, conf.min, conf.max, conf.unit), (1.0, 0.0, 0.0, 100.0, "%"));
}
