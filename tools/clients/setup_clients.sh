#!/bin/bash
# The Python environment the clients' preprocessing imports, as CLIENTS/venv (outside this repository): the
# project's own interpreter and CPU torch (system site packages) plus the clients' pure-Python requirements at the
# versions checked here on 2026-12-02; OSMesa for DNF-Avatar's pyrender overlay. CUDA-only modules are not
# installed: py/sitecustomize.py stands in for them.
set -euo pipefail
: "${CLIENTS:?set CLIENTS to the folder holding the three client checkouts}"
command -v apt-get >/dev/null && [ ! -e /usr/lib/x86_64-linux-gnu/libOSMesa.so.8 ] && \
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libosmesa6 >/dev/null
python -m venv --system-site-packages "$CLIENTS/venv"
P="$CLIENTS/venv/bin/pip"
"$P" install -q smplx==0.1.28 h5py==3.16.0 scikit-video==1.1.11 wget==3.2 opencv-python-headless==4.14.0.94 \
  imageio==2.38.2 omegaconf==2.3.1 hydra-core==1.3.8 wandb==0.31.0 plotly==7.1.0 pytorch-lightning==1.9.5 \
  einops==0.8.2 PyMCubes==0.1.6 pyransac3d==0.7.0 pyexr==0.5.0 tensorboard==2.21.0 rich==15.0.0 \
  pytorch-msssim==1.0.0 libigl==2.6.3 plyfile==1.1.5 kornia==0.9.0 tabulate==0.10.0 termcolor==3.3.0 \
  pyrender==0.1.45 torchgeometry==0.1.2 "setuptools<70"
"$P" install -q --no-deps lpips==0.1.4 nerfacc==0.5.3 torch_efficient_distloss==0.1.3 PyOpenGL==3.1.9
# some of the above pull a CUDA torch into the venv: the project's CPU torch (system site packages) is the one to use
"$P" uninstall -y -q torch 2>/dev/null || true
echo "client venv ready: $CLIENTS/venv"
