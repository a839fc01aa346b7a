#!/usr/bin/env bash
# Installs every build and run dependency of amt from Debian packages (docs/architecture.md, "The layers of the code").
# Idempotent: packages already present are skipped; `apt-get update` runs at most once, and only
# when something is missing. Needs root (or sudo) only when it has something to install.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  ccache                # a second checkout reuses the first one's objects (CMakeLists.txt)
  libtorch-dev          # LibTorch 1.13, CPU
  libgloo-dev           # Gloo's headers, which c10d's ProcessGroupGloo.hpp includes (data-parallel training)
  libopenblas0-pthread  # LibTorch's BLAS: ~35x faster matrix products than the reference BLAS
  libeigen3-dev libtinygltf-dev libtinyobjloader-dev libhdf5-dev zlib1g-dev libcli11-dev
  libgtest-dev libbullet-dev nlohmann-json3-dev libnanoflann-dev
  libopenvdb-dev libboost-dev libtbb-dev
  gnuplot-nox           # report plots (PNG)
  libstb-dev            # stb_image_write: PNG pictures of characters (data_tools/formats/render.h)
  libcgal-dev           # exact triangle-triangle intersection tests of the garment refit (tests/refit)
  libcpp-httplib-dev    # the local HTTP server of `amt view`
  chromium              # the headless browser of the viewer's test (tests/viewer/)
)

# Node runs the Khronos glTF validator (npm package gltf-validator) in tests. The machine image may
# carry a nodesource build whose nodejs package bundles npm (and conflicts with Debian's npm), so
# Debian's node packages are only asked for when the commands are absent.
command -v node >/dev/null 2>&1 || packages+=(nodejs)
command -v npm >/dev/null 2>&1 || packages+=(npm)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages present"
else
  echo "setup: installing ${missing[*]}"
  sudo_cmd=()
  if [ "$(id -u)" -ne 0 ]; then sudo_cmd=(sudo); fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -q
  "${sudo_cmd[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The Khronos glTF validator, pinned by tools/gltf-validator/package-lock.json (the npm registry).
validator_dir="$(dirname "$0")/../tools/gltf-validator"
if [ ! -d "$validator_dir/node_modules/gltf-validator" ]; then
  echo "setup: installing the glTF validator (npm ci in tools/gltf-validator)"
  (cd "$validator_dir" && npm ci --no-audit --no-fund --loglevel=error)
fi
# The web viewer's three.js (and playwright-core, which drives Chromium in its test), pinned by
# viewer/package-lock.json.
viewer_dir="$(dirname "$0")/../viewer"
if [ ! -d "$viewer_dir/node_modules/three" ] || [ ! -d "$viewer_dir/node_modules/playwright-core" ]; then
  echo "setup: installing the viewer's three.js and playwright-core (npm ci in viewer)"
  (cd "$viewer_dir" && npm ci --no-audit --no-fund --loglevel=error)
fi
echo "setup: done"
