#!/usr/bin/env bash
# Sets up dpcbench on a fresh Debian/Ubuntu machine: the system libraries open3d needs, a virtual
# environment in .venv, and the package (editable). `./install.sh --dev` adds the test tools,
# Dask, the headless browser the dashboard test uses and pdflatex (the LaTeX tables test compiles them).
set -euo pipefail
cd "$(dirname "$0")"
dev=0
[ "${1:-}" = "--dev" ] && dev=1

packages="python3-venv libusb-1.0-0 libgomp1 libgl1 libegl1"
[ "$dev" = 1 ] && packages="$packages chromium"
# pdflatex and booktabs, without their recommends (fonts and docs): the tests compile the LaTeX tables
tex_packages=""
[ "$dev" = 1 ] && tex_packages="texlive-latex-base texlive-latex-recommended"
missing_of() {
  local out=""
  for p in "$@"; do
    dpkg -s "$p" >/dev/null 2>&1 || out="$out $p"
  done
  echo "$out"
}
if command -v apt-get >/dev/null 2>&1 && command -v dpkg >/dev/null 2>&1; then
  missing="$(missing_of $packages)"
  missing_tex="$(missing_of $tex_packages)"
  if [ -n "$missing$missing_tex" ]; then
    sudo=""
    [ "$(id -u)" = 0 ] || sudo="sudo"
    echo "installing system packages:$missing$missing_tex"
    $sudo apt-get update -qq
    [ -z "$missing" ] || DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq $missing >/dev/null
    [ -z "$missing_tex" ] || DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
      $missing_tex >/dev/null
  fi
fi

python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
target="."
[ "$dev" = 1 ] && target=".[dev,dask]"
# constraints.txt: the versions CI passed with (results and the bit-exact tests depend on them); where
# they cannot be installed (e.g. another Python version without those wheels), the newest ones are
if ! .venv/bin/python -m pip install -q -c constraints.txt -e "$target"; then
  echo "install.sh: the versions in constraints.txt could not be installed here; installing the newest ones" >&2
  .venv/bin/python -m pip install -q -e "$target"
fi
echo "dpcbench installed in .venv: run .venv/bin/dpcbench --help"
