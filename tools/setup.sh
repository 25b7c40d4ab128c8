#!/usr/bin/env bash
# Set up a fresh machine for tai_coll: the system libraries headless rendering needs
# (Vulkan's loader and Mesa's software driver, lavapipe, for machines without a GPU driver),
# then a virtual environment in .venv with tai_coll, its USD export (usd-core), its sweeps on
# Ray (ray, pillow) and its test dependencies.
# Safe to run again: it skips what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
for pkg in libvulkan1 mesa-vulkan-drivers; do
  dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if [ ${#need[@]} -gt 0 ]; then
  if command -v apt-get >/dev/null 2>&1; then
    sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    echo "setup: installing ${need[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  else
    echo "setup: no apt-get here; install Vulkan (libvulkan1) and a Vulkan driver yourself for rendering" >&2
  fi
fi

python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q -e ".[usd,sweep,test]"
echo "setup: done (.venv ready)"
