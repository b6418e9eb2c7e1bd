"""The generator as stages: protocol spec -> plan -> subjects -> one frame at a time -> dataset folder.

    seeding   (seed, purpose, keys)             -> an independent random generator per choice
    plan      spec, settings, seed, out          -> DatasetPlan, its FrameTasks (checked by resolve_plan)
    folder    DatasetPlan                        -> dataset.json, character.json (refusing to mix datasets)
    subjects  DatasetPlan                        -> SubjectSource: anny or imported subjects, their poses
    frames    plan, source, subject, split, i    -> one frame's files on disk (render_frame_to_disk); its render
                                                  stage's input per camera, FrameScene (frame_scenes, render_scene)
    run       DatasetPlan, Backend               -> the whole dataset, manifest.json last (generate)

Backends (rh_dataset.backends) import these stages and are handed to `generate`; nothing here imports them.
"""
from rh_dataset.generate.frames import (FrameResult, FrameScene, OnFrame, exposure_for, frame_scenes,
                                        render_frame_to_disk, render_scene, run_subject)
from rh_dataset.generate.plan import (DATASET_FORMAT, DatasetPlan, FrameTask, GenerateError, frame_tasks,
                                      resolve_plan)
from rh_dataset.generate.run import Backend, generate
from rh_dataset.generate.seeding import rng_for
from rh_dataset.generate.subjects import Subject, SubjectSource, subject_source

__all__ = ["generate", "Backend", "DatasetPlan", "FrameTask", "FrameResult", "OnFrame", "GenerateError",
           "DATASET_FORMAT", "frame_tasks", "resolve_plan", "rng_for", "exposure_for",
           "render_frame_to_disk", "run_subject", "FrameScene", "frame_scenes", "render_scene", "Subject",
           "SubjectSource", "subject_source"]
