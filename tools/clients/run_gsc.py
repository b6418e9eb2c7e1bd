"""Run the data-reading cells (0-4) of Gaussian Shadow Casting's rana_to_h5.ipynb, unchanged except the two path
placeholders a user edits in cell 3 (and cell 4's output file)."""
import json
import sys

nb_path, smpl_pkl, subject_dir, out_h5 = sys.argv[1:5]
nb = json.load(open(nb_path))
cells = ["\n".join(l for l in "".join(c["source"]).splitlines() if not l.lstrip().startswith(("%", "!"))) for c in nb["cells"] if c["cell_type"] == "code"][:5]
cells[3] = cells[3].replace("./PATH TO SMPL/SMPL_NEUTRAL.pkl", smpl_pkl).replace(
    "./PATH TO RANA/RelightingHumans-release-v0.1/train_p2_p3/subject_01/", subject_dir)
cells[4] = cells[4].replace("./data/RANA/subject_01_train.h5", out_h5)
g = {"__name__": "__main__"}
for i, src in enumerate(cells):
    print(f"--- GSC cell {i}", flush=True)
    exec(compile(src, f"rana_to_h5.ipynb[cell {i}]", "exec"), g)
import h5py
with h5py.File(out_h5) as f:
    print("h5:", {k: f[k].shape for k in f.keys()})
