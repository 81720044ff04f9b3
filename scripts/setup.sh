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

if ! command -v qemu-system-arm >/dev/null 2>&1; then
    echo "setup: installing qemu-system-arm (apt)"
    SUDO=""
    if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq qemu-system-arm >/dev/null
fi
qemu-system-arm --version | head -n1
