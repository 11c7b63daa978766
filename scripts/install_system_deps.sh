#!/usr/bin/env bash
# Debian libraries for headless rendering (MuJoCo via EGL or OSMesa), Open3D (libusb) and the
# browser the report test opens its page in (chromium, headless).
# Installs only what is missing; needs root (or sudo) the first time.
set -euo pipefail
pkgs=(libegl1 libegl-mesa0 libgl1 libosmesa6 libusb-1.0-0 chromium)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "installing Debian packages: ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
