#!/usr/bin/env bash
# Regenerates every case's STEP file from its .geo script (gmsh + OpenCASCADE). The STEP files are
# committed, so this is only needed after editing a .geo file.
set -euo pipefail
cd "$(dirname "$0")"
for geo in */*.geo; do
  # A .geo whose first lines say "format: brep" is in metres and exported as BREP (no unit);
  # the others are in millimetres and exported as STEP (which gmsh declares in millimetres).
  if head -n 3 "$geo" | grep -q "format: brep"; then fmt=brep; else fmt=step; fi
  out="${geo%.geo}.$fmt"
  gmsh -0 "$geo" -o "$out" -format "$fmt" >/dev/null
  echo "wrote $out"
done
