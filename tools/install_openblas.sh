#!/bin/sh
# Install Debian's OpenBLAS for CHOLMOD (called by `make setup`; issue 13).
# CHOLMOD's supernodal factorisation runs on whatever libblas.so.3 the system provides;
# libopenblas0-pthread registers itself there (update-alternatives) and is 1.4x-6.5x faster than
# the reference BLAS that libsuitesparse-dev brings. Never fails: without OpenBLAS, set-up goes on
# and says so in one line. OPENBLAS_GLOB (tests) overrides where an installed one is looked for.
GLOB=${OPENBLAS_GLOB:-/usr/lib/*-linux-gnu/openblas*/libblas.so.3}
# shellcheck disable=SC2086  # the glob must expand
if ls $GLOB >/dev/null 2>&1; then
  exit 0
fi
echo "installing OpenBLAS for CHOLMOD (libopenblas0-pthread)"
SUDO=$(command -v sudo >/dev/null && [ "$(id -u)" != 0 ] && echo sudo)
if { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libopenblas0-pthread; } \
    >/dev/null 2>&1; then
  exit 0
fi
echo "warning: could not install OpenBLAS; CHOLMOD runs on the reference BLAS (slower)"
exit 0
