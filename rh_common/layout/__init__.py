"""The one owner of the dataset and predictions layout (docs/ARCHITECTURE.md, "Dataset layout", "Frame JSON",
"Predictions layout").

In: folders, frame coordinates, layers and frame metadata. Out: names and paths (`paths`), the typed frame JSON
(`record`), frame files written and checked (`frames`), the manifest and content identity (`manifest`), two
datasets compared (`compare`), the body-pose reader (`pose`).
Everything that writes or reads a dataset — rh-generate's writer, rh-verify, rana, rh-eval, the exporters, the
bench and the test fakes — goes through here, so the format exists once.
"""
from .compare import (COMPARISON_FORMAT, NOISE_TOLERANCE, TIERS, TOLERANCE, Comparison, compare_datasets,
                      metadata_difference, read_comparison)
from .frames import LAYERS, frame_is_complete, layer_files, write_frame
from .manifest import (MANIFEST_FORMAT, ManifestEntry, check_entry, content_identity, read_identity, read_manifest,
                       split_identity, split_key, unlisted_files, write_manifest)
from .paths import (CHARACTER_JSON, CONTACT_SHEET, DATASET_JSON, LOG_DIR, MANIFEST_JSON, METHOD_JSON,
                    PREDICTION_FILE_RE, PREDICTION_LAYERS, TEST_SPLIT, frame_index_of, frame_json_name, frame_json_path, frame_stem,
                    iter_frame_jsons, layer_file_name, prediction_dir, prediction_file, protocol_dir, protocol_of,
                    split_dir, splits_of, subject_index, subject_name, view_name, view_index, view_dir, views_of,
                    frame_folders, frame_key)
from .pose import PoseArrays, read_body_pose, rigid_matrix
from .record import FRAME_FORMAT, FileEntry, FrameRecord, read_frame_record, write_frame_record

__all__ = [
    "CHARACTER_JSON", "CONTACT_SHEET", "DATASET_JSON", "LOG_DIR", "MANIFEST_JSON", "METHOD_JSON", "TEST_SPLIT",
    "subject_name", "subject_index", "protocol_dir", "protocol_of", "split_dir", "frame_stem", "frame_json_name",
    "frame_json_path", "layer_file_name", "frame_index_of", "iter_frame_jsons", "splits_of",
    "view_name", "view_index", "view_dir", "views_of", "frame_folders", "frame_key",
    "PREDICTION_LAYERS", "PREDICTION_FILE_RE", "prediction_dir", "prediction_file",
    "FRAME_FORMAT", "FileEntry", "FrameRecord", "read_frame_record", "write_frame_record",
    "LAYERS", "layer_files", "write_frame", "frame_is_complete",
    "MANIFEST_FORMAT", "ManifestEntry", "write_manifest", "read_manifest", "unlisted_files", "check_entry",
    "read_identity", "content_identity", "split_key", "split_identity",
    "PoseArrays", "read_body_pose", "rigid_matrix",
    "COMPARISON_FORMAT", "NOISE_TOLERANCE", "TIERS", "TOLERANCE", "Comparison", "compare_datasets",
    "metadata_difference", "read_comparison",
]
