# Shared set-up for scripts/voxelscope and scripts/test: system packages (Debian/Ubuntu, when missing) and a
# virtual environment in .venv with Voxelscope installed (editable) plus its test tools. Idempotent and quick when
# everything is in place. Sourced, not run.

VOXELSCOPE_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VOXELSCOPE_VENV="${VOXELSCOPE_VENV:-$VOXELSCOPE_ROOT/.venv}"

# X server for tests, and the X/EGL/GL libraries Qt (xcb platform) and VTK need on a fresh Debian machine; mricron-data
# holds real atlases (AAL label volume) that the label-volume tests and screenshots use.
VOXELSCOPE_APT_PACKAGES=(
  python3 python3-venv python3-pip
  xvfb xauth
  libgl1 libegl1 libglx-mesa0 libgl1-mesa-dri libglu1-mesa
  libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0
  libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xkb1 libxcb-xfixes0 libxcb-shm0 libxcb-sync1
  libx11-xcb1 libxrender1 libxi6 libxtst6 libxext6 libsm6 libice6
  libdbus-1-3 libfontconfig1 libfreetype6 fonts-dejavu-core
  mricron-data
)

voxelscope_install_system_packages() {
  command -v dpkg-query >/dev/null 2>&1 || return 0   # not Debian: the user installs these themselves
  local missing=()
  for package in "${VOXELSCOPE_APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "Installing system packages: ${missing[*]}" >&2
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -q
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
}

voxelscope_install_python() {
  if [ ! -x "$VOXELSCOPE_VENV/bin/python" ]; then
    echo "Creating the virtual environment $VOXELSCOPE_VENV" >&2
    python3 -m venv "$VOXELSCOPE_VENV"
  fi
  local stamp="$VOXELSCOPE_VENV/.voxelscope-installed"
  if [ ! -f "$stamp" ] || [ "$VOXELSCOPE_ROOT/pyproject.toml" -nt "$stamp" ]; then
    echo "Installing Voxelscope and its dependencies into $VOXELSCOPE_VENV" >&2
    "$VOXELSCOPE_VENV/bin/python" -m pip install --quiet --upgrade pip
    "$VOXELSCOPE_VENV/bin/python" -m pip install --quiet -e "$VOXELSCOPE_ROOT[test]"
    touch "$stamp"
  fi
}

voxelscope_setup() {
  voxelscope_install_system_packages
  voxelscope_install_python
}
