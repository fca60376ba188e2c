#!/usr/bin/env bash
# Regenerates every case's STEP file from its .geo script (gmsh + OpenCASCADE). The STEP files are
# committed, so this is only needed after editing a .geo file.
set -euo pipefail
cd "$(dirname "$0")"
for geo in */*.geo; do
  step="${geo%.geo}.step"
  gmsh -0 "$geo" -o "$step" -format step >/dev/null
  echo "wrote $step"
done
