//! Fuzz target: the CAN decoder must never panic on any frame sequence, and every frame it
//! accepts must be canonical (re-encoding the decoded report with its counter gives back the
//! very same frame), with the heartbeat timeout in play. The same bytes are also fed as a
//! candump log through `host-sim can decode`.
#![no_main]

use embedded_can::{ExtendedId, Frame, Id, StandardId};
use libfuzzer_sys::fuzz_target;
use pbm::can::codec::status_link;
use pbm::can::layout::{FAULT_REPORT, STATUS};
use pbm::can::{decode_frame, encode_fault, encode_session, encode_status, Binding, CanFrame, Decoder, Report};
use pbm_lab::can_cmd::{decode_log, CabDisplay, DecodeFormat};

/// Frames from bytes: a header byte (bits 0-3 length, 4 extended, 5 remote, 6-7 id choice:
/// fault, status, or the next 4 bytes as a raw id), then the id and data bytes.
fn frames(mut data: &[u8]) -> Vec<CanFrame> {
    let mut out = Vec::new();
    while let Some((&h, rest)) = data.split_first() {
        data = rest;
        let len = usize::from(h & 0x0F).min(8);
        let id: Id = match h >> 6 {
            0 => ExtendedId::new(FAULT_REPORT.raw_id()).unwrap().into(),
            1 => ExtendedId::new(STATUS.raw_id()).unwrap().into(),
            _ => {
                let mut raw = [0u8; 4];
                let n = data.len().min(4);
                raw[..n].copy_from_slice(&data[..n]);
                data = &data[n..];
                let raw = u32::from_le_bytes(raw);
                if h & 0x10 != 0 {
                    ExtendedId::new(raw & 0x1FFF_FFFF).unwrap().into()
                } else {
                    StandardId::new((raw & 0x7FF) as u16).unwrap().into()
                }
            }
        };
        let f = if h & 0x20 != 0 {
            CanFrame::new_remote(id, len).unwrap()
        } else {
            let n = data.len().min(len);
            let f = CanFrame::new(id, &data[..n]).unwrap();
            data = &data[n..];
            f
        };
        out.push(f);
    }
    out
}

fuzz_target!(|data: &[u8]| {
    let mut decoder = Decoder::new();
    // Frames 1 s apart, so runs of non-status frames also exercise the heartbeat timeout.
    for (i, f) in frames(data).into_iter().enumerate() {
        let reception = decoder.receive(i as u64 * 1_000_000, &f);
        if let Ok(report) = reception.result {
            let identity = reception.identity.expect("an accepted frame is attributed");
            // A fault report of a session whose count a session frame gave is sealed with that
            // count and the unit's fleet number (layout 3.2); without one, as a young unit's.
            if reception.release_count.is_some() && matches!(report, Report::Fault(_)) {
                continue;
            }
            let binding = Binding::young(identity);
            let (again, counter) = decode_frame(&f, binding).expect("stream-accepted frames decode alone");
            assert_eq!(again, report);
            let re = match report {
                Report::Fault(r) => encode_fault(&r, counter as u8, binding),
                Report::Status(s) => {
                    encode_status(&s, status_link(u64::from_le_bytes(f.data().try_into().expect("8 bytes"))))
                }
                Report::Session(l) => encode_session(l),
            };
            assert_eq!(re, f);
            assert!(f.is_extended() && f.dlc() == 8);
        }
    }
    let mut display = CabDisplay::new(std::io::sink(), true, DecodeFormat::Text);
    decode_log(data, &mut display).expect("writing to a sink cannot fail");
    let s = display.finish().expect("sink");
    assert_eq!(s.frames, s.fault_reports + s.status_reports + s.flagged_total());
});
