#!/usr/bin/env bash
# Installs what modbot needs beyond the Rust toolchain, where it is missing (run it again: it
# skips what is there):
# - libclang, for the `fmi` crate, which generates its FMI bindings with bindgen at build time
#   (Debian/Ubuntu: libclang-dev, through apt-get; elsewhere install it and set LIBCLANG_PATH);
# - the HDF5 C library and its headers, for the data recorder (`hdf5-metno`: Debian/Ubuntu
#   libhdf5-dev, through apt-get; elsewhere install HDF5 1.10 or newer and set HDF5_DIR);
# - with --tests, Python's h5py (the tests read the recordings with it) and FMPy (the tests
#   validate and simulate the FMUs with it), through pip; iproute2 (`ip`: the EtherCAT
#   tests make a network namespace and a veth pair) and Debian's chromium (the station's
#   browser tests) and tmux (the test of `modbot top` types into it), through apt-get; and
#   playwright-core, which drives chromium, through npm
#   into tests/browser/node_modules (its version pinned by tests/browser/package-lock.json).
set -euo pipefail

have_libclang() {
    [ -n "${LIBCLANG_PATH:-}" ] && return 0
    compgen -G "/usr/lib/llvm-*/lib/libclang.so" > /dev/null
}

have_hdf5() {
    [ -n "${HDF5_DIR:-}" ] && return 0
    compgen -G "/usr/include/hdf5/serial/hdf5.h" > /dev/null || [ -e /usr/include/hdf5.h ]
}

missing=()
have_libclang || missing+=(libclang-dev)
have_hdf5 || missing+=(libhdf5-dev)
if [ "${1:-}" = "--tests" ] && ! command -v ip > /dev/null; then
    missing+=(iproute2)
fi
if [ "${1:-}" = "--tests" ] && [ ! -x /usr/bin/chromium ]; then
    missing+=(chromium)
fi
if [ "${1:-}" = "--tests" ] && ! command -v tmux > /dev/null; then
    missing+=(tmux)
fi
if [ "${1:-}" = "--tests" ] && ! command -v npm > /dev/null; then
    missing+=(nodejs npm)
fi
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]} (libclang for the fmi crate's bindgen, HDF5 for the recorder, iproute2 for the EtherCAT tests, chromium for the station's browser tests, tmux for modbot top's)"
    sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" > /dev/null
fi

if [ "${1:-}" = "--tests" ] && ! python3 -c "import h5py, fmpy, mcap" 2> /dev/null; then
    echo "setup: installing h5py, FMPy and mcap (for the tests)"
    python3 -m pip install --quiet --disable-pip-version-check "h5py>=3.8" "fmpy==0.3.32" "mcap>=1.1,<2"
fi

here="$(cd "$(dirname "$0")" && pwd)"
if [ "${1:-}" = "--tests" ] && [ ! -d "$here/tests/browser/node_modules/playwright-core" ]; then
    echo "setup: installing playwright-core (for the station's browser tests)"
    (cd "$here/tests/browser" && npm ci --no-audit --no-fund --silent)
fi
