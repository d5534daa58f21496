#!/usr/bin/env bash
# Make sure wgpu finds an adapter. On a machine without one, install Mesa's CPU Vulkan driver
# (lavapipe) from Debian when running as root; otherwise say what to install.
set -u
py="${1:-.venv/bin/python}"
probe() {
  XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}" "$py" - <<'PY' 2>/dev/null
import sys, wgpu
try:
    a = wgpu.gpu.request_adapter_sync(power_preference="high-performance")
except Exception:
    a = None
if a is None:
    sys.exit(1)
print(f"adapter: {a.info['device']} ({a.info['backend_type']})")
PY
}
probe && exit 0
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "no WebGPU adapter found: installing mesa-vulkan-drivers (lavapipe)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null && apt-get install -y -qq mesa-vulkan-drivers >/dev/null
  probe && exit 0
fi
echo "error: no WebGPU adapter found. Install a GPU driver with Vulkan, or Mesa's CPU driver:" >&2
echo "  sudo apt-get install mesa-vulkan-drivers" >&2
exit 1
