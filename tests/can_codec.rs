//! CAN codec, E2E protection, stream decoder and transmit schedule of `pbm::can`.

use embedded_can::{ExtendedId, Frame, Id, StandardId};
use pbm::can::layout::{self, FAULT_REPORT, STATUS};
use pbm::can::reporter::{FAULT_MIN_GAP_SAMPLES, FAULT_REPEAT_SAMPLES, STATUS_PERIOD_SAMPLES};
use pbm::can::{
    decode_frame, encode_fault, encode_status, quantize_fault, CanFrame, CanReporter, Decoder, FrameError, Report,
};
use pbm::report::{EstimatorState, FaultReport, NoDiagnosis, StatusReport, Verdict};
use pbm::sensor::SensorFault;
use pbm::FaultClass;
use proptest::prelude::*;

fn verdict() -> impl Strategy<Value = Verdict> {
    prop_oneof![
        (prop::sample::select(FaultClass::ALL.to_vec()), 0..=100u8)
            .prop_map(|(class, confidence_pct)| Verdict::Class { class, confidence_pct }),
        prop::sample::select(
            SensorFault::ALL
                .map(NoDiagnosis::SensorFault)
                .into_iter()
                .chain([NoDiagnosis::TooShort, NoDiagnosis::Unfamiliar])
                .collect::<Vec<_>>()
        )
        .prop_map(Verdict::CannotDiagnose),
    ]
}

fn fault_report() -> impl Strategy<Value = FaultReport> {
    (verdict(), any::<u16>(), any::<u16>(), any::<u16>(), any::<bool>()).prop_map(|(verdict, t, s, l, c)| FaultReport {
        verdict,
        time_since_release_cs: t,
        supply_mbar: s,
        leak_um: l,
        release_completed: c,
    })
}

fn status_report() -> impl Strategy<Value = StatusReport> {
    (
        prop::sample::select(core::iter::once(None).chain(SensorFault::ALL.map(Some)).collect::<Vec<_>>()),
        prop::sample::select(vec![
            EstimatorState::Idle,
            EstimatorState::Converging,
            EstimatorState::Settled,
            EstimatorState::Frozen,
        ]),
        any::<u16>(),
        any::<(u8, u8)>(),
    )
        .prop_map(|(sensor_fault, estimator, pressure_mbar, version)| StatusReport {
            sensor_fault,
            estimator,
            pressure_mbar,
            version,
        })
}

fn example_fault() -> FaultReport {
    FaultReport {
        verdict: Verdict::Class { class: FaultClass::AirLeak, confidence_pct: 90 },
        time_since_release_cs: 2_540,
        supply_mbar: 7_700,
        leak_um: 850,
        release_completed: false,
    }
}

fn example_status() -> StatusReport {
    StatusReport { sensor_fault: None, estimator: EstimatorState::Converging, pressure_mbar: 4_070, version: (0, 1) }
}

/// Flips one bit of the data of a frame (same id, same length).
fn flip_data_bit(f: &CanFrame, bit: usize) -> CanFrame {
    let mut data = [0u8; 8];
    data[..f.dlc()].copy_from_slice(f.data());
    data[bit / 8] ^= 1 << (bit % 8);
    CanFrame::new(f.id(), &data[..f.dlc()]).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn fault_round_trip(r in fault_report(), counter in 0u8..16) {
        let f = encode_fault(&r, counter);
        prop_assert_eq!(f.raw_id(), FAULT_REPORT.raw_id());
        prop_assert!(f.is_extended() && f.is_data_frame() && f.dlc() == 8);
        let q = quantize_fault(&r);
        prop_assert_eq!(decode_frame(&f), Ok((Report::Fault(q), counter)));
        // Quantisation is idempotent, exact on the grid, and within half a step inside the range.
        prop_assert_eq!(quantize_fault(&q), q);
        prop_assert_eq!(decode_frame(&encode_fault(&q, counter)), Ok((Report::Fault(q), counter)));
        if r.time_since_release_cs <= 40_950 {
            prop_assert!(q.time_since_release_cs.abs_diff(r.time_since_release_cs) <= 5);
        } else {
            prop_assert_eq!(q.time_since_release_cs, 40_950);
        }
        if r.supply_mbar <= 20_475 {
            prop_assert!(q.supply_mbar.abs_diff(r.supply_mbar) <= 2);
        } else {
            prop_assert_eq!(q.supply_mbar, 20_475);
        }
        prop_assert_eq!(q.leak_um, r.leak_um.min(4095));
        prop_assert_eq!(q.verdict, r.verdict);
        prop_assert_eq!(q.release_completed, r.release_completed);
    }

    #[test]
    fn status_round_trip_is_lossless(s in status_report(), counter in 0u8..16) {
        let f = encode_status(&s, counter);
        prop_assert_eq!(f.raw_id(), STATUS.raw_id());
        prop_assert_eq!(decode_frame(&f), Ok((Report::Status(s), counter)));
    }

    /// Arbitrary frames never panic the decoder; whatever it accepts is a canonical frame
    /// (re-encoding the decoded report with its counter gives back the very same frame).
    #[test]
    fn arbitrary_frames_never_panic(
        extended in any::<bool>(),
        raw_id in any::<u32>(),
        remote in any::<bool>(),
        data in prop::collection::vec(any::<u8>(), 0..=8),
        use_known_id in any::<bool>(),
    ) {
        let id: Id = if use_known_id {
            ExtendedId::new(if raw_id % 2 == 0 { FAULT_REPORT.raw_id() } else { STATUS.raw_id() }).unwrap().into()
        } else if extended {
            ExtendedId::new(raw_id & 0x1FFF_FFFF).unwrap().into()
        } else {
            StandardId::new((raw_id & 0x7FF) as u16).unwrap().into()
        };
        let f = if remote { CanFrame::new_remote(id, data.len()).unwrap() } else { CanFrame::new(id, &data).unwrap() };
        let mut dec = Decoder::new();
        for _ in 0..3 {
            if let Ok(report) = dec.decode(&f) {
                let (again, counter) = decode_frame(&f).unwrap();
                prop_assert_eq!(again, report);
                let re = match report {
                    Report::Fault(r) => encode_fault(&r, counter),
                    Report::Status(s) => encode_status(&s, counter),
                };
                prop_assert_eq!(re, f);
            }
        }
    }

    /// Random payloads under the monitor's own ids: only a matching CRC gets through (and then
    /// only canonical content), so about 1 in 256 pass the CRC.
    #[test]
    fn random_payloads_fail_crc_or_are_canonical(data in any::<[u8; 8]>(), fault in any::<bool>()) {
        let id = if fault { FAULT_REPORT.raw_id() } else { STATUS.raw_id() };
        let f = CanFrame::new_extended(id, &data).unwrap();
        match decode_frame(&f) {
            Err(FrameError::WrongCrc { .. }) | Err(FrameError::InvalidSignal { .. }) => {}
            Ok((Report::Fault(r), c)) => prop_assert_eq!(encode_fault(&r, c), f),
            Ok((Report::Status(s), c)) => prop_assert_eq!(encode_status(&s, c), f),
            Err(e) => prop_assert!(false, "unexpected {:?}", e),
        }
    }

    /// Every single-bit flip of the data, the identifier or the length is detected.
    #[test]
    fn every_single_bit_flip_is_detected(r in fault_report(), s in status_report(), counter in 0u8..16) {
        for f in [encode_fault(&r, counter), encode_status(&s, counter)] {
            for bit in 0..64 {
                let bad = flip_data_bit(&f, bit);
                prop_assert!(matches!(decode_frame(&bad), Err(FrameError::WrongCrc { .. })), "data bit {}", bit);
            }
            for bit in 0..29 {
                let bad = CanFrame::new_extended(f.raw_id() ^ (1 << bit), f.data()).unwrap();
                let err = decode_frame(&bad).unwrap_err();
                prop_assert!(matches!(err, FrameError::UnknownId { .. } | FrameError::WrongCrc { .. }), "id bit {}", bit);
            }
            // Standard-format frame with the same low 11 bits: unknown.
            let std = CanFrame::new_standard((f.raw_id() & 0x7FF) as u16, f.data()).unwrap();
            prop_assert!(matches!(decode_frame(&std), Err(FrameError::UnknownId { extended: false, .. })), "standard id");
            // A DLC bit flip changes the length: every other length is rejected.
            for len in 0..8 {
                let bad = CanFrame::new(f.id(), &f.data()[..len]).unwrap();
                prop_assert_eq!(decode_frame(&bad), Err(FrameError::WrongLength { expected: 8, got: len as u8 }));
            }
            let rtr = CanFrame::new_remote(f.id(), 8).unwrap();
            prop_assert!(matches!(decode_frame(&rtr), Err(FrameError::RemoteFrame { .. })), "remote frame");
        }
    }
}

#[test]
fn id_bit_8_turns_fault_into_status_id_and_the_data_id_catches_it() {
    // 0x18FF5080 and 0x18FF5180 differ in one bit: the per-message data ID in the CRC is what
    // stops a fault report being read as a status frame.
    let f = encode_fault(&example_fault(), 3);
    let bad = CanFrame::new_extended(f.raw_id() ^ 0x100, f.data()).unwrap();
    assert_eq!(bad.raw_id(), STATUS.raw_id());
    assert!(matches!(decode_frame(&bad), Err(FrameError::WrongCrc { .. })));
}

#[test]
fn known_answer_vectors() {
    // Pinned bytes: a change of layout or CRC shows up here (and must be mirrored in the DBC).
    let f = encode_fault(&example_fault(), 5);
    assert_eq!(f.raw_id(), 0x18FF_5080);
    let s = encode_status(&example_status(), 9);
    assert_eq!(s.raw_id(), 0x18FF_5180);
    // Layout by hand: diag 1 << 12 | counter 5 << 8; confidence 90 % in bits 16..23; reason 0
    // in bits 23..27; completed 0; time 254 << 28; supply 1540 << 40; leak 850 << 52.
    let bits = (1u64 << 12) | (5 << 8) | (90 << 16) | (254 << 28) | (1540 << 40) | (850 << 52);
    let mut payload = bits.to_le_bytes();
    payload[0] = pbm::can::codec::e2e_crc(0xFF50, &payload);
    assert_eq!(f.data(), payload);
    // CRC-8 SAE J1850 check value: "123456789" -> 0x4B.
    let crc = crc::Crc::<u8>::new(&crc::CRC_8_SAE_J1850);
    assert_eq!(crc.checksum(b"123456789"), 0x4B);
    let sb = (9u64 << 8) | (1 << 14) | (4070 << 16) | (1 << 40);
    let mut payload = sb.to_le_bytes();
    payload[0] = pbm::can::codec::e2e_crc(0xFF51, &payload);
    assert_eq!(s.data(), payload);
}

#[test]
fn invalid_signal_values_with_good_crc_are_flagged() {
    let seal = |id: u32, data_id: u16, bits: u64| {
        let mut p = bits.to_le_bytes();
        p[0] = pbm::can::codec::e2e_crc(data_id, &p);
        CanFrame::new_extended(id, &p).unwrap()
    };
    let cases: [(u32, u16, u64, &str); 9] = [
        (FAULT_REPORT.raw_id(), 0xFF50, 6 << 12, "Diagnosis"),
        (FAULT_REPORT.raw_id(), 0xFF50, 15 << 12 | 14 << 23, "NoDiagnosisReason"),
        (FAULT_REPORT.raw_id(), 0xFF50, 1 << 12 | 5 << 23, "NoDiagnosisReason"),
        (FAULT_REPORT.raw_id(), 0xFF50, 15 << 12, "NoDiagnosisReason"),
        (FAULT_REPORT.raw_id(), 0xFF50, 15 << 12 | 3 << 23 | 7 << 16, "Confidence"),
        (FAULT_REPORT.raw_id(), 0xFF50, 2 << 12 | 101 << 16, "Confidence"),
        (STATUS.raw_id(), 0xFF51, 3 << 48, "SensorHealth"),
        (STATUS.raw_id(), 0xFF51, 1 << 12, "reserved"),
        (STATUS.raw_id(), 0xFF51, 1 << 60, "reserved"),
    ];
    for (id, data_id, bits, name) in cases {
        match decode_frame(&seal(id, data_id, bits)) {
            Err(FrameError::InvalidSignal { signal, .. }) => assert_eq!(signal, name),
            other => panic!("{name}: {other:?}"),
        }
    }
}

/// Sequence faults: each replayed, dropped or reordered frame is flagged, the rest decode.
#[test]
fn replayed_dropped_and_reordered_frames_are_detected() {
    let frames: Vec<CanFrame> = (0..40u8).map(|i| encode_fault(&example_fault(), i)).collect();
    let labels = |order: &[usize]| -> Vec<Option<&'static str>> {
        let mut d = Decoder::new();
        order.iter().map(|&i| d.decode(&frames[i]).err().map(|e| e.label())).collect()
    };
    // In order, across two counter wraps: all good.
    assert!(labels(&(0..40).collect::<Vec<_>>()).iter().all(Option::is_none));
    // Replay of the last frame.
    assert_eq!(labels(&[0, 1, 2, 2, 3]), [None, None, None, Some("repeated_counter"), None]);
    // Replay of an old frame later on.
    assert_eq!(labels(&[0, 1, 2, 3, 4, 1, 5]), [None, None, None, None, None, Some("out_of_order"), None]);
    // Dropped frames (one, and seven).
    assert_eq!(labels(&[0, 1, 3, 4]), [None, None, Some("skipped_counter"), None]);
    assert_eq!(labels(&[0, 1, 9, 10]), [None, None, Some("skipped_counter"), None]);
    // Reordered pair.
    assert_eq!(labels(&[0, 1, 3, 2, 4]), [None, None, Some("skipped_counter"), Some("out_of_order"), None]);
    // Counters are per message: interleaved status frames do not disturb the fault sequence.
    let mut d = Decoder::new();
    for i in 0..20u8 {
        assert_eq!(d.decode(&encode_status(&example_status(), i)), Ok(Report::Status(example_status())));
        assert_eq!(d.decode(&encode_fault(&example_fault(), i)), Ok(Report::Fault(quantize_fault(&example_fault()))));
    }
}

#[test]
fn reporter_schedule() {
    let status = example_status();
    let mut fault = example_fault();
    let mut rep = CanReporter::new();
    let mut dec = Decoder::new();
    let mut sent: Vec<(u32, CanFrame)> = Vec::new();
    for n in 0..1000u32 {
        // A release of 6 s: the report appears at 1 s, its verdict changes at 3 s, then
        // the supply estimate wanders every sample from 4 s to 4.5 s.
        let active = n < 600;
        fault.time_since_release_cs = n as u16;
        if n == 300 {
            fault.verdict = Verdict::Class { class: FaultClass::LeakAndBlock, confidence_pct: 78 };
        }
        if (400..450).contains(&n) {
            fault.supply_mbar = 7_000 + 10 * n as u16;
        }
        let report = (n >= 100).then_some(&fault);
        for f in rep.step(&status, report, active).as_slice() {
            assert!(dec.decode(f).is_ok(), "every scheduled frame decodes cleanly at sample {n}");
            sent.push((n, *f));
        }
    }
    let status_at: Vec<u32> = sent.iter().filter(|(_, f)| f.raw_id() == STATUS.raw_id()).map(|(n, _)| *n).collect();
    assert_eq!(status_at, (0..10).map(|k| k * STATUS_PERIOD_SAMPLES).collect::<Vec<_>>());
    let fault_at: Vec<u32> =
        sent.iter().filter(|(_, f)| f.raw_id() == FAULT_REPORT.raw_id()).map(|(n, _)| *n).collect();
    // Appears at 100, repeated at 1 Hz, changes at 300, the wandering supply is sent every
    // 10 samples, repeats resume from the last change, nothing after the release ends at 600.
    assert_eq!(fault_at, [100, 200, 300, 400, 410, 420, 430, 440, 450, 550]);
    assert!(fault_at.windows(2).all(|w| w[1] - w[0] >= FAULT_MIN_GAP_SAMPLES));
    assert!(fault_at.windows(2).all(|w| w[1] - w[0] <= FAULT_REPEAT_SAMPLES));
    // The frames carry the report as it was when sent.
    let (_, f) = sent.iter().find(|(n, f)| *n == 300 && f.raw_id() == FAULT_REPORT.raw_id()).unwrap();
    match decode_frame(f).unwrap().0 {
        Report::Fault(r) => {
            assert_eq!(r.verdict, Verdict::Class { class: FaultClass::LeakAndBlock, confidence_pct: 78 });
            assert_eq!(r.time_since_release_cs, 300);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn reporter_is_deterministic() {
    let run = || {
        let mut rep = CanReporter::new();
        let mut out = Vec::new();
        for n in 0..500u32 {
            let mut r = example_fault();
            r.time_since_release_cs = n as u16;
            out.extend_from_slice(rep.step(&example_status(), Some(&r), true).as_slice());
        }
        out
    };
    assert_eq!(run(), run());
    assert_eq!(run().len(), 5 + 5);
    // Sanity on the layout constants used by the schedule.
    assert_eq!(layout::MESSAGES.len(), 2);
}

/// Beyond single bits: every 2-bit error anywhere in the 8 data bytes is detected, checked
/// exhaustively. (Not every 3-bit error is: CRC-8 SAE J1850 has Hamming distance 3 at this
/// length, e.g. mask 0x0000020000000003 slips through; the counter and the display's plausibility
/// are the next line of defence, and the frame is report-only.)
#[test]
fn every_double_bit_error_is_detected() {
    let frames = [encode_fault(&example_fault(), 7), encode_status(&example_status(), 12)];
    for f in frames {
        let base = u64::from_le_bytes(f.data().try_into().unwrap());
        let check = |mask: u64| {
            let bad = CanFrame::new(f.id(), &(base ^ mask).to_le_bytes()).unwrap();
            assert!(matches!(decode_frame(&bad), Err(FrameError::WrongCrc { .. })), "mask {mask:016X}");
        };
        for a in 0..64 {
            for b in a + 1..64 {
                check(1 << a | 1 << b);
            }
        }
    }
}

// ---- heartbeat rule -------------------------------------------------------------------------

/// A silent heartbeat (no status frame for longer than HEARTBEAT_TIMEOUT_US) restarts counter
/// tracking, so a restarted sender is accepted; shorter gaps keep the sequence checks.
#[test]
fn heartbeat_loss_restarts_counter_tracking() {
    use pbm::can::HEARTBEAT_TIMEOUT_US;
    assert_eq!(HEARTBEAT_TIMEOUT_US, 3_000_000);
    let status = |c: u8| encode_status(&example_status(), c);
    let fault = |c: u8| encode_fault(&example_fault(), c);
    let mut d = Decoder::new();
    let mut t = 0u64;
    for c in 0..5u8 {
        let r = d.receive(t, &status(c));
        assert!(r.result.is_ok() && r.heartbeat_lost_us.is_none());
        t += 1_000_000;
    }
    assert!(d.receive(t, &fault(0)).result.is_ok());
    // The sender restarts after a gap shorter than the timeout: its counter 0 is a replay.
    let r = d.receive(4_000_000 + HEARTBEAT_TIMEOUT_US, &status(0));
    assert_eq!((r.result.map_err(|e| e.label()), r.heartbeat_lost_us), (Err("out_of_order"), None));
    // The same after a silence longer than the timeout: lost, resynchronised, accepted.
    let mut d2 = Decoder::new();
    assert!(d2.receive(0, &status(7)).result.is_ok());
    assert!(d2.receive(100, &fault(3)).result.is_ok());
    let r = d2.receive(HEARTBEAT_TIMEOUT_US + 1, &fault(0));
    assert_eq!(r.heartbeat_lost_us, Some(HEARTBEAT_TIMEOUT_US + 1));
    assert!(r.result.is_ok(), "restarted fault sequence accepted");
    let r = d2.receive(HEARTBEAT_TIMEOUT_US + 2, &status(0));
    assert_eq!((r.result.is_ok(), r.heartbeat_lost_us), (true, None), "restarted status sequence accepted");
    // Sequence checks work again at once after the resync.
    assert_eq!(d2.receive(HEARTBEAT_TIMEOUT_US + 3, &status(0)).result.unwrap_err().label(), "repeated_counter");
    // Only status frames with a valid CRC are heartbeats: fault reports and corrupted status
    // frames do not keep the monitor alive.
    let mut d3 = Decoder::new();
    assert!(d3.receive(0, &status(1)).result.is_ok());
    assert!(d3.receive(2_000_000, &fault(1)).result.is_ok());
    let bad = flip_data_bit(&status(2), 20);
    assert_eq!(d3.receive(2_500_000, &bad).result.unwrap_err().label(), "wrong_crc");
    assert!(d3.receive(3_000_001, &fault(2)).heartbeat_lost_us.is_some());
    // A status frame flagged only for its counter still proves the sender alive.
    let mut d4 = Decoder::new();
    assert!(d4.receive(0, &status(1)).result.is_ok());
    assert_eq!(d4.receive(2_000_000, &status(1)).result.unwrap_err().label(), "repeated_counter");
    assert!(d4.receive(4_000_000, &status(2)).heartbeat_lost_us.is_none());
    // A clock going backwards is no silence.
    assert!(d4.receive(0, &status(3)).heartbeat_lost_us.is_none());
}

// ---- what the pipeline transmits ------------------------------------------------------------

/// Checks one frame the pipeline wants to send: one of the two DBC messages, extended id,
/// 8-byte data frame, and it decodes cleanly in sequence.
fn assert_report_frame(f: &CanFrame, dec: &mut Decoder, t_us: u64, seen: &mut [u32; 2]) {
    let idx = layout::MESSAGES
        .iter()
        .position(|m| m.raw_id() == f.raw_id())
        .unwrap_or_else(|| panic!("pipeline emitted id {:08X}, not one of the DBC's messages", f.raw_id()));
    assert!(f.is_extended() && f.is_data_frame() && f.dlc() == 8, "{f:?}");
    seen[idx] += 1;
    let r = dec.receive(t_us, f);
    assert!(r.result.is_ok(), "pipeline frame flagged: {:?}", r.result);
    assert!(r.heartbeat_lost_us.is_none());
}

/// The monitor never transmits anything but its two report identifiers: full releases of
/// every class (and sensor faults) through the one per-sample pipeline shared with the
/// firmware, with every frame checked and decoded in sequence.
#[test]
fn pipeline_emits_only_the_two_report_ids() {
    use pbm::pipeline::Pipeline;
    use pbm::sensor::adc_from_bar;
    use pbm::{AdcCounts, Twin, TwinParams};
    let nominal = TwinParams::nominal();
    let releases = [
        nominal,
        nominal.with_leak_mm(0.9),
        nominal.with_orifice_mm(0.5),
        nominal.with_supply_bar_g(5.0),
        nominal.with_orifice_mm(3.0),
    ];
    let mut pipe = Pipeline::nominal().unwrap();
    let mut dec = Decoder::new();
    let mut seen = [0u32; 2];
    let mut n = 0u64;
    for (k, params) in releases.iter().enumerate() {
        let mut plant = Twin::new(params).unwrap();
        let mut p = pbm::PressureQ24::ATMOSPHERE;
        // Valve open for 30 s (a sensor fault in the middle of release 1), then 5 s closed.
        for i in 0..3500u32 {
            let open = i < 3000;
            let mut adc = adc_from_bar(p.to_bar_g());
            if k == 1 && (1000..1100).contains(&i) {
                adc = AdcCounts(if i < 1050 { 0 } else { 4095 });
            }
            let step = pipe.step(adc, open);
            p = plant.update(open).pressure;
            for f in step.frames.as_slice() {
                assert_report_frame(f, &mut dec, n * 10_000, &mut seen);
            }
            n += 1;
        }
    }
    assert_eq!(pipe.close(), None);
    assert!(seen[0] >= releases.len() as u32, "fault reports sent: {seen:?}");
    assert_eq!(u64::from(seen[1]), n.div_ceil(100), "status at 1 Hz");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Whatever the inputs (any ADC code, even above 12 bits; any valve pattern), the pipeline
    /// emits only the two report frames, each decoding cleanly in sequence.
    #[test]
    fn pipeline_emits_only_report_frames_for_any_input(
        segments in prop::collection::vec((any::<bool>(), 1u32..700, any::<u16>(), -40i32..40), 1..8),
    ) {
        let mut pipe = pbm::pipeline::Pipeline::nominal().unwrap();
        let mut dec = Decoder::new();
        let mut seen = [0u32; 2];
        let mut n = 0u64;
        for (open, len, start, slope) in segments {
            for i in 0..len {
                let adc = (i64::from(start) + i64::from(slope) * i64::from(i)).clamp(0, i64::from(u16::MAX)) as u16;
                for f in pipe.step(pbm::AdcCounts(adc), open).frames.as_slice() {
                    assert_report_frame(f, &mut dec, n * 10_000, &mut seen);
                }
                n += 1;
            }
        }
        if let Some((_, frames)) = pipe.close() {
            for f in frames.as_slice() {
                assert_report_frame(f, &mut dec, n * 10_000, &mut seen);
            }
        }
        prop_assert!(seen[1] >= 1, "a status frame from the first sample");
    }
}
