#!/usr/bin/env python3
"""Decode every frame of a candump log with cantools (an off-the-shelf DBC tool) against
can/brake_monitor.dbc and check the values equal host-sim's own decoding.

The fault report's CRC covers the locomotive and release number of the sender (carried by
the status frame, not by the fault report): host-sim's CSV names the pair it attributed each
report to, and this script checks it is the last status frame's (or its next release) and that
the CRC over it matches. A session frame must follow its status frame (same heartbeat counter,
locomotive, and release number = the low 6 bits of its release count).

Usage: can_cantools_check.py DBC LOG HOST_SIM_CSV [--require-all-labels]

HOST_SIM_CSV is `host-sim can decode --format csv LOG`: one row per frame, in log order, with
physical values. For every frame this script also
  - recomputes the E2E CRC (CRC-8 SAE J1850 over the data ID and bytes 1..7) independently,
  - re-encodes cantools' raw decoding and checks it gives back the very same bytes.
Exit status 0 when every frame matches, 1 otherwise.
"""
import csv
import sys

import cantools
import cantools.logreader

DATA_IDS = {"BPM_FaultReport": 0x2F50, "BPM_Status": 0x2F51, "BPM_Session": 0x3F52}
# The fault report's CRC also covers the sender identity the status frame carries.
IDENTITY_SIGNALS = ("Locomotive", "ReleaseNumber")
CRC_SIGNAL = {"BPM_FaultReport": "FaultCrc", "BPM_Status": "StatusCrc", "BPM_Session": "SessionCrc"}
COUNTER_SIGNAL = {"BPM_FaultReport": "FaultCounter", "BPM_Status": "StatusCounter",
                  "BPM_Session": "SessionStatusCounter"}
# host-sim's CSV column of a signal, where the names differ.
COLUMN = {"SessionLocomotive": "Locomotive", "SessionLocomotiveHigh": "Locomotive"}


def crc8_sae_j1850(data: bytes) -> int:
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def main() -> int:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    require_all = "--require-all-labels" in sys.argv
    if len(args) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    dbc_path, log_path, csv_path = args
    db = cantools.database.load_file(dbc_path)
    assert crc8_sae_j1850(b"123456789") == 0x4B, "CRC-8 SAE J1850 check value"

    with open(log_path) as f:
        frames = [fr for fr in cantools.logreader.Parser(f) if fr is not None]
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    errors = []
    if len(frames) != len(rows):
        errors.append(f"{len(frames)} frames in the log but {len(rows)} rows from host-sim")

    seen = {}
    counts = {}
    identity = {"Locomotive": 0, "ReleaseNumber": 0}  # of the last status frame (0, 0 before one)
    last_status_counter = None
    for i, (fr, row) in enumerate(zip(frames, rows)):
        where = f"frame {i + 1} ({fr.frame_id:08X}#{fr.data.hex().upper()})"
        try:
            msg = db.get_message_by_frame_id(fr.frame_id)
        except KeyError:
            errors.append(f"{where}: not in the DBC")
            continue
        if not msg.is_extended_frame:
            errors.append(f"{where}: DBC says standard id")
        if row["message"] != msg.name or row["flag"]:
            errors.append(f"{where}: host-sim says {row['message']!r} flag {row['flag']!r}, DBC says {msg.name}")
            continue
        counts[msg.name] = counts.get(msg.name, 0) + 1
        data = bytes(fr.data)
        raw = db.decode_message(fr.frame_id, data, decode_choices=False, scaling=False)
        phys = db.decode_message(fr.frame_id, data, decode_choices=True, scaling=True)

        # E2E, independently of the Rust code: data ID, then (fault report) the locomotive and
        # release number of the status frame (host-sim's attribution, which this checks), then
        # bytes 1..7.
        if msg.name == "BPM_Status":
            identity = {k: raw[k] for k in IDENTITY_SIGNALS}
            last_status_counter = raw["StatusCounter"]
            implicit = b""
        elif msg.name == "BPM_Session":
            # Sent right after its status frame: same heartbeat counter, locomotive and release
            # number (the count's low 6 bits).
            implicit = b""
            ours = (raw["SessionStatusCounter"], raw["SessionLocomotive"], raw["ReleaseCount"] % 64)
            theirs = (last_status_counter, identity["Locomotive"], identity["ReleaseNumber"])
            if ours != theirs:
                errors.append(f"{where}: session frame (counter, locomotive, release) {ours}, "
                              f"the status frame before it {theirs}")
            if int(row["ReleaseNumber"]) != raw["ReleaseCount"] % 64:
                errors.append(f"{where}: host-sim release number {row['ReleaseNumber']}")
        else:
            loco, release = int(row["Locomotive"]), int(row["ReleaseNumber"])
            implicit = bytes([loco, release])
            if (loco, release) not in {(identity.get("Locomotive"), identity.get("ReleaseNumber")),
                                       (identity.get("Locomotive"), (identity.get("ReleaseNumber", -1) + 1) % 64)}:
                errors.append(f"{where}: host-sim attributes it to locomotive {loco} release {release}, "
                              f"the last status frame says {identity}")
        crc = crc8_sae_j1850(DATA_IDS[msg.name].to_bytes(2, "little") + implicit + data[1:])
        if raw[CRC_SIGNAL[msg.name]] != crc:
            errors.append(f"{where}: CRC {raw[CRC_SIGNAL[msg.name]]:02X}, expected {crc:02X}")
        if int(row["counter"]) != raw[COUNTER_SIGNAL[msg.name]]:
            errors.append(f"{where}: counter host-sim {row['counter']} vs cantools {raw[COUNTER_SIGNAL[msg.name]]}")
        # host-sim's attribution of the frame to a full release count (when a session frame gave
        # one) agrees with the release number it names.
        if row.get("ReleaseCount") and int(row["ReleaseCount"]) % 64 != int(row["ReleaseNumber"]):
            errors.append(f"{where}: release count {row['ReleaseCount']} is not release {row['ReleaseNumber']}")
        # Re-encoding cantools' own decoding gives back the frame (no bits outside the DBC).
        again = db.encode_message(fr.frame_id, raw, scaling=False, strict=True)
        if bytes(again) != data:
            errors.append(f"{where}: cantools re-encodes to {bytes(again).hex().upper()}")

        for sig in msg.signals:
            if sig.name in (CRC_SIGNAL[msg.name], COUNTER_SIGNAL[msg.name]):
                continue
            ours = row[COLUMN.get(sig.name, sig.name)]
            # host-sim's session row gives the 12-bit fleet number; the DBC splits it in two.
            if sig.name == "SessionLocomotive":
                ours = int(ours) % 64
            elif sig.name == "SessionLocomotiveHigh":
                ours = int(row["Locomotive"]) // 64
            theirs = phys[sig.name]
            if sig.choices:
                label = theirs.name if hasattr(theirs, "name") else str(theirs)
                seen.setdefault(sig.name, set()).add(label)
                if label != ours:
                    errors.append(f"{where}: {sig.name} host-sim {ours!r} vs cantools {label!r}")
            else:
                if abs(float(ours) - float(theirs)) > 1e-9:
                    errors.append(f"{where}: {sig.name} host-sim {ours} vs cantools {theirs}")

    if require_all:
        for msg in db.messages:
            for sig in msg.signals:
                if sig.choices:
                    labels = {str(v) for v in sig.choices.values()}
                    missing = labels - seen.get(sig.name, set())
                    if missing:
                        errors.append(f"{msg.name}.{sig.name}: labels never seen in the log: {sorted(missing)}")

    for e in errors[:50]:
        print("MISMATCH", e)
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    print(f"cantools {cantools.__version__}: {len(frames)} frames checked ({summary}); {len(errors)} mismatches")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
