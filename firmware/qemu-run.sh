#!/usr/bin/env bash
# Runner of the QEMU firmware builds (`runner` in .cargo/config.toml): `qemu-run.sh ELF [ARGS]`.
#
# Standard output is the firmware's semihosting standard output as is (the `monitor` binary's
# candump log, compared byte for byte with the host's). Standard error carries the firmware's
# defmt log frames (firmware/src/console.rs); they are decoded here with `defmt-print`, which
# reads the format strings from the ELF (they are not in the flash image), one message a line.
# The exit status is QEMU's, i.e. the firmware's semihosting exit status (124: timed out).
#
#   -icount shift=0,sleep=off  one instruction = 1 ns of virtual time, and while the CPU sleeps
#                              in WFI the virtual clock jumps to the next timer deadline: runs are
#                              deterministic and 60 s of 100 Hz ticker time take well under 1 s.
#   timeout 120                a hung firmware fails instead of blocking CI.
set -u
elf=$1
shift
if ! command -v defmt-print >/dev/null 2>&1; then
    echo "qemu-run.sh: defmt-print not found (install it with \`cargo xtask setup\`)" >&2
    exit 127
fi
exec 3>&1
timeout 120 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -icount shift=0,sleep=off -kernel "$elf" "$@" \
    2>&1 1>&3 3>&- | defmt-print -e "$elf" --log-format '{s}' >&2 3>&-
exit "${PIPESTATUS[0]}"
