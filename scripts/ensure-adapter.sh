#!/usr/bin/env bash
# Make sure wgpu finds a good adapter. Vulkan (or Metal/D3D12) is preferred: on a machine that
# offers only OpenGL, Mesa's CPU Vulkan driver (lavapipe) is installed from Debian when running as
# root; otherwise this says what to install and carries on with OpenGL, which pycinder also runs
# on. With no adapter at all it fails with the same advice.
set -u
py="${1:-.venv/bin/python}"
probe() {
  # Prints the backend of the adapter wgpu picks by default ("Vulkan", "OpenGL", ...).
  XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp}" "$py" - <<'PY' 2>/dev/null
import sys, wgpu
try:
    a = wgpu.gpu.request_adapter_sync(power_preference="high-performance")
except Exception:
    a = None
if a is None:
    sys.exit(1)
print(a.info["backend_type"], "-", a.info["device"])
PY
}
found=$(probe) || found=""
case "$found" in
  Vulkan*|Metal*|D3D12*) echo "adapter: $found"; exit 0 ;;
esac
if [ -n "$found" ] && [ -n "${WGPU_BACKEND_TYPE:-}" ]; then
  # The backend was chosen on purpose (WGPU_BACKEND_TYPE=OpenGL): take it as it is.
  echo "adapter: $found (WGPU_BACKEND_TYPE=$WGPU_BACKEND_TYPE)"
  exit 0
fi
if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
  echo "adapter: ${found:-none}; installing mesa-vulkan-drivers (lavapipe, Mesa's CPU Vulkan driver)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null && apt-get install -y -qq mesa-vulkan-drivers >/dev/null
  found=$(probe) || found=""
  case "$found" in
    Vulkan*) echo "adapter: $found"; exit 0 ;;
  esac
fi
if [ -n "$found" ]; then
  echo "adapter: $found (no Vulkan driver: for the faster Vulkan path install Mesa's CPU driver," \
       "sudo apt-get install mesa-vulkan-drivers)"
  exit 0
fi
echo "error: no WebGPU adapter found. Install a GPU driver with Vulkan, or Mesa's CPU driver:" >&2
echo "  sudo apt-get install mesa-vulkan-drivers" >&2
exit 1
