#!/usr/bin/env bash
# Make a virtual environment with LeRobot, a CPU build of PyTorch, busarm and busarm's
# LeRobot plugin (docs/lerobot.md says why these versions).
#   integrations/lerobot/venv/install.sh VENV [PYTHON]
# TORCH_INDEX: where the CPU build of torch 2.13.0 comes from when pip's own settings do
# not have it on this computer (default: PyTorch's CPU index; never PyPI's, a CUDA build).
set -euo pipefail
# torchcodec (LeRobot's video decoder) loads the system's FFmpeg libraries (4 to 8: Debian
# 12 has 5.1); libavdevice-dev brings them all by the same name on Debian and Ubuntu.
ffmpeg_libs="libavdevice-dev"
if ! ldconfig -p | grep -q 'libavdevice\.so\.'; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing FFmpeg's libraries for LeRobot's video decoding"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $ffmpeg_libs >/dev/null
  else
    echo "LeRobot's video decoding needs FFmpeg's libraries: sudo apt-get install $ffmpeg_libs" >&2
    exit 1
  fi
fi
here="$(cd "$(dirname "$0")" && pwd)"
repo="$(cd "$here/../../.." && pwd)"
venv="$1"
python="${2:-python3}"
torch_index="${TORCH_INDEX:-https://download.pytorch.org/whl/cpu}"
rm -rf "$venv"
"$python" -m venv "$venv"
pip=("$venv/bin/python" -m pip install -q --disable-pip-version-check)
"${pip[@]}" --upgrade pip
# The CPU build first: asked for through another package, pip would take a CUDA build.
# One on this computer (pip's find-links) if there is one, else PyTorch's CPU index.
if "${pip[@]}" --no-index --no-deps torch==2.13.0 2>/dev/null; then
  "${pip[@]}" torch==2.13.0  # its own dependencies, from the usual index
else
  "${pip[@]}" torch==2.13.0 --index-url "$torch_index" --extra-index-url https://pypi.org/simple
fi
"$venv/bin/python" -c 'import torch, sys; sys.exit(torch.version.cuda is not None)' \
  || { echo "torch 2.13.0 here is a CUDA build: give TORCH_INDEX a CPU build's index" >&2; exit 1; }
# LeRobot 0.4.4 pins torch<2.11, torchvision<0.26 and torchcodec<0.11, which have no CPU
# build for this Python here: its other dependencies with their own pins, then LeRobot, and
# the torchvision and torchcodec made for torch 2.13, without dependencies.
"${pip[@]}" -r "$here/requirements.txt" -c "$here/constraints.txt"
"${pip[@]}" --no-deps torchvision==0.28.0 torchcodec==0.13.0 lerobot==0.4.4
site="$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
cp "$here/torchvision_ops.py" "$site/_busarm_torchvision_ops.py"
echo "import _busarm_torchvision_ops; _busarm_torchvision_ops.install()" > "$site/_busarm_torchvision_ops.pth"
"${pip[@]}" -e "$repo[dev]" -c "$here/constraints.txt"
"${pip[@]}" --no-deps -e "$repo/integrations/lerobot"
"$venv/bin/python" -c 'import torchvision, lerobot, lerobot_robot_busarm'
