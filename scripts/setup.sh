#!/usr/bin/env bash
# Installs what the project needs on a fresh machine: the Cortex-M4F Rust target and QEMU.
# Idempotent: does nothing that is already done.
set -euo pipefail

if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
    echo "setup: adding Rust target thumbv7em-none-eabihf"
    rustup target add thumbv7em-none-eabihf
fi
for c in rustfmt clippy; do
    if ! rustup component list --installed | grep -q "^$c"; then
        rustup component add "$c"
    fi
done

# qemu-system-arm runs the firmware; llvm's size/nm read the firmware ELF for the cost report.
missing=()
command -v qemu-system-arm >/dev/null 2>&1 || missing+=(qemu-system-arm)
command -v llvm-size >/dev/null 2>&1 || command -v arm-none-eabi-size >/dev/null 2>&1 || missing+=(llvm)
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]} (apt)"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}" >/dev/null
fi
qemu-system-arm --version | head -n1
