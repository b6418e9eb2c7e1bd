"""Offline CPU harness for the published clients (tools/clients/run_clients.sh): our code, not theirs.

Stands in only for what cannot run on a CPU-only, offline machine: CUDA-only modules (`STUBS`: tinycudann, kaolin,
pytorch3d, the Gaussian rasterisers, IntrinsicAvatar's absent lib/torch_pbr submodule, ...), the fast_snarf CUDA JIT
(torch.utils.cpp_extension.load) and torchvision's CUDA wheel (../torchvision: to_tensor only); it maps .cuda() and
device="cuda" to the CPU. The clients' preprocessing never calls into a stub: a stub that is called returns a dummy. requests.get is served from $HARNESS_HDRI_DIR (the files a user downloads first); everything else
reaching the network fails."""
import importlib.abc
import importlib.machinery
import os
import sys
import types

STUBS = {"tinycudann", "gs_ir", "renderutils", "renderutils_plugin", "torchmcubes", "open3d", "glfw", "apex", "diff_surfel_rasterization", "diff_gaussian_rasterization", "simple_knn", "simple_knn._C", "pytorch3d", "pytorch3d.ops", "pytorch3d.ops.knn", "pytorch3d.transforms", "pytorch3d.structures", "pytorch3d.renderer", "kaolin", "kaolin.ops", "kaolin.ops.mesh", "kaolin.metrics", "kaolin.metrics.trianglemesh", "lib.torch_pbr", "nvdiffrast", "nvdiffrast.torch", "nerfacc_cuda"}


class _AnyMeta(type):
    def __getattr__(cls, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return _Anything()

    def __or__(cls, other):
        return cls


class _Anything(metaclass=_AnyMeta):
    def __or__(self, other):
        return self

    def __init__(self, *a, **k):
        pass

    def __call__(self, *a, **k):
        return _Anything()

    def __getattr__(self, name):
        return _Anything()


class _StubModule(types.ModuleType):
    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return type(name, (_Anything,), {})


class _StubFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, name, path=None, target=None):
        if name in STUBS:
            return importlib.machinery.ModuleSpec(name, self, is_package=True)
        return None

    def create_module(self, spec):
        m = _StubModule(spec.name)
        m.__path__ = []
        return m

    def exec_module(self, module):
        pass


sys.meta_path.insert(0, _StubFinder())

try:
    import torch
    import torch.utils.cpp_extension as _ce

    torch.Tensor.cuda = lambda self, *a, **k: self
    torch.nn.Module.cuda = lambda self, *a, **k: self
    _ce.load = lambda *a, **k: _Anything()  # fast_snarf's CUDA kernels, compiled at import

    def _cpu(dev):
        return "cpu" if (isinstance(dev, str) and dev.startswith("cuda")) or (
            isinstance(dev, torch.device) and dev.type == "cuda") else dev

    def _wrap(fn):
        def f(*a, **k):
            if "device" in k:
                k["device"] = _cpu(k["device"])
            return fn(*a, **k)
        return f

    for _n in ("zeros", "ones", "empty", "full", "eye", "arange", "linspace", "rand", "randn", "randint", "tensor",
               "as_tensor", "zeros_like", "ones_like", "empty_like", "full_like"):
        setattr(torch, _n, _wrap(getattr(torch, _n)))
    _to = torch.Tensor.to

    def _tensor_to(self, *a, **k):
        a = tuple(_cpu(x) for x in a)
        if "device" in k:
            k["device"] = _cpu(k["device"])
        return _to(self, *a, **k)

    torch.Tensor.to = _tensor_to
    _mto = torch.nn.Module.to

    def _module_to(self, *a, **k):
        a = tuple(_cpu(x) for x in a)
        if "device" in k:
            k["device"] = _cpu(k["device"])
        return _mto(self, *a, **k)

    torch.nn.Module.to = _module_to
except ImportError:
    pass

try:
    import requests

    class _Resp:
        def __init__(self, path):
            self.path, self.status_code = path, 200

        def iter_content(self, chunk_size=1 << 20):
            with open(self.path, "rb") as fh:
                while True:
                    b = fh.read(chunk_size)
                    if not b:
                        return
                    yield b

        @property
        def content(self):
            with open(self.path, "rb") as fh:
                return fh.read()

    def _get(url, *a, **k):
        folder = os.environ.get("HARNESS_HDRI_DIR")
        name = url.rstrip("/").rsplit("/", 1)[-1]
        with open(os.environ.get("HARNESS_LOG", "/dev/null"), "a") as fh:
            fh.write(f"requests.get {url} -> {folder}/{name}\n")
        if folder and os.path.isfile(os.path.join(folder, name)):
            return _Resp(os.path.join(folder, name))
        raise ConnectionError(f"offline harness: {url} is not in HARNESS_HDRI_DIR={folder}")

    requests.get = _get
except ImportError:
    pass
