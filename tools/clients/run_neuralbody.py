"""Load a rh-export --format zju-mocap sequence with NeuralBody's own dataset class (zju3dv/neuralbody,
lib/datasets/light_stage/multi_view_dataset.py) and check what its network needs: 6890 SMPL vertices (its latent
codes are nn.Embedding(6890, 16)) and the SMPL box projected with its camera covering the person's mask.
A multi-camera sequence (protocol c's `capture/`) names its training cameras in annots['rh']['training_view']: they
become NeuralBody's cfg.training_view, and its test split then reads every other camera of the sequence.

    cd /path/to/neuralbody && PYTHONPATH=.:TOOLS/clients/py python TOOLS/clients/run_neuralbody.py SEQ_DIR N_FRAMES

Run from a NeuralBody checkout (its config module parses sys.argv at import, so the settings go there)."""
import sys

seq, n_frames = sys.argv[1], int(sys.argv[2])
import numpy as np  # noqa: E402

annots = np.load(f"{seq}/annots.npy", allow_pickle=True).item()
import imageio  # noqa: E402

h, w = imageio.imread(f"{seq}/{annots['ims'][0]['ims'][0]}").shape[:2]
training_view = list(annots.get("rh", {}).get("training_view", [0]))
sys.argv = ["neuralbody", "--cfg_file", "configs/zju_mocap_exp/latent_xyzc_313.yaml", "exp_name", "rh_check",
            "training_view", str(training_view).replace(" ", ""), "num_train_frame", str(n_frames), "begin_ith_frame", "0", "frame_interval", "1",
            "H", str(h), "W", str(w), "ratio", "1.0", "vertices", "vertices", "params", "params"]
from lib.datasets.light_stage.multi_view_dataset import Dataset  # noqa: E402

bad = 0
for split in ("train", "test"):
    ds = Dataset(seq, "rh", f"{seq}/annots.npy", split)
    for i in range(len(ds)):
        item = ds[i]
        n_vert = item["coord"].shape[0]
        line = f"{split} item {i}: coord {item['coord'].shape} out_sh {item['out_sh']} rays {item['ray_o'].shape}"
        if split == "test":
            msk = ds.get_mask(i) == 1
            box = item["mask_at_box"].reshape(h, w)
            cover = float((msk & box).sum() / max(msk.sum(), 1))
            line += f", person's mask inside the projected SMPL box: {cover:.3f}"
            bad += cover < 0.95
        bad += n_vert != 6890
        print(line, flush=True)
print(f"training views {training_view} of {len(annots['cams']['K'])} cameras")
print("neuralbody check:", "ok" if not bad else f"{bad} problem(s)")
sys.exit(1 if bad else 0)
