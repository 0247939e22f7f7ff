#!/usr/bin/env bash
# Rebuilds three.bundle.js from the pinned three.js of package-lock.json (npm registry), when the
# pin or entry.js changes. The bundle is committed: building isotopo needs neither Node.js nor
# the network; the report embeds the bundle, compressed.
set -euo pipefail
cd "$(dirname "$0")"
npm ci --no-audit --no-fund
npx esbuild entry.js --bundle --minify --format=iife --global-name=THREE \
  --legal-comments=none --outfile=three.bundle.js
cp node_modules/three/LICENSE LICENSE-three.txt
echo "three $(node -p "require('./node_modules/three/package.json').version") bundled: $(wc -c < three.bundle.js) bytes"
