#!/usr/bin/env bash
# scripts/hmi.sh open | build | check | e2e - the web HMI (web/).
#   open:  the HMI on the simulated mill: builds rtcnc and runs `rtcnc serve` on
#          http://127.0.0.1:8080 (users and programs in target/hmi-demo; the first start
#          prints the admin's one-time password). Needs no Node.js.
#   build: install the npm packages of web/package-lock.json, generate the API types from
#          docs/openapi.json, build the bundle into web/dist (committed: the rtcnc binary
#          embeds it, so a Rust build needs no Node).
#   check: the types, the unit tests (vitest), and that the committed bundle and API types
#          are what web/ and docs/openapi.json build to, byte for byte.
#   e2e:   the end-to-end tests: headless Chromium (Debian's) against a real rtcnc serve.
# Needs Node.js 20 and npm (and for e2e Debian's chromium-headless-shell, which
# scripts/setup.sh installs when asked: scripts/test.sh does).
set -euo pipefail
cd "$(dirname "$0")/../web"
what=${1:-check}

if [ "$what" = open ]; then
  cd ..
  cargo build -p rtcnc --locked
  mkdir -p target/hmi-demo
  echo "the HMI: http://127.0.0.1:8080 (Ctrl-C stops the machine)"
  exec target/debug/rtcnc serve --machine configs/sim-mill.toml \
    --users target/hmi-demo/users.toml --programs target/hmi-demo/programs
fi

if ! command -v node >/dev/null || ! node -e 'const [a,b]=process.versions.node.split(".").map(Number); process.exit(a>20||(a==20&&b>=19)?0:1)'; then
  echo "the web HMI needs Node.js 20.19 or newer with npm (found: $(node --version 2>/dev/null || echo none))" >&2
  exit 2
fi
stamp=node_modules/.installed
if [ ! -f "$stamp" ] || [ package-lock.json -nt "$stamp" ]; then
  npm ci --no-audit --no-fund --loglevel=error
  touch "$stamp"
fi

case "$what" in
  build)
    npx openapi-typescript ../docs/openapi.json -o src/api/schema.d.ts >/dev/null
    npx tsc --noEmit
    npx vite build --logLevel warn
    du -sb dist/assets/* | sort -k2
    ;;
  check)
    tmp=$(mktemp -d)
    trap 'rm -rf "$tmp"' EXIT
    npx openapi-typescript ../docs/openapi.json -o "$tmp/schema.d.ts" >/dev/null
    if ! cmp -s "$tmp/schema.d.ts" src/api/schema.d.ts; then
      echo "web/src/api/schema.d.ts is not generated from docs/openapi.json: run scripts/hmi.sh build" >&2
      exit 1
    fi
    npx tsc --noEmit
    npx vitest run
    npx vite build --logLevel warn --outDir "$tmp/dist" --emptyOutDir
    if ! diff -r "$tmp/dist" dist >/dev/null; then
      diff -r "$tmp/dist" dist | head -5 >&2
      echo "web/dist is not the build of web/: run scripts/hmi.sh build and commit web/dist" >&2
      exit 1
    fi
    echo "web/dist is the build of web/ ($(du -sb dist | cut -f1) bytes)"
    ;;
  e2e)
    node --test --test-concurrency=1 e2e/
    ;;
  *)
    echo "usage: scripts/hmi.sh open | build | check | e2e" >&2
    exit 2
    ;;
esac
