"""Rule report_twin_keypoints: the twin's 2D keypoints against its truth, beside the published figures
their rates come from (twin runs only)."""

import numpy as np
import pandas as pd

from pingpong.common.artifacts import read_json, read_table
from pingpong.common.atomic import write_text_atomic
from pingpong.common.camera import Camera
from pingpong.reports import twin_keypoints as tk
from pingpong.twin import truth
from pingpong.twin.openpose_sim import KeypointErrors

TITLE = "The twin's 2D keypoints against its truth"
CAPTION = """Every session's OpenPose JSON of each camera (rule twin_openpose) against the people's true
joints projected through the true rig. A detection is a player's when its median joint distance to the
player's projection is under half the player's object scale s (COCO's: the root of the person's area, here
0.53 of the joints' bounding box); a detection that is no player's is a false person (the bystander beside
the table, the spectator walking behind a court). Per joint (left and right pooled), over the players'
joints inside the image: the 2D error of joints in plain view (swaps left out) as a share of s beside what
the configured detector should make (sigma_scale x COCO's sigma x sqrt(ln 2), the median of a circular
Gaussian error of that RMS; motion blur adds to it on fast joints), in px, and as a share of the player's
joints' height in the image; the error of hidden joints (behind the own trunk or a nearer person); the
median confidence of reported joints in plain view, hidden and swapped; the
share of joints hidden; misses (a joint in the image written as 0, 0, 0) in view (as its other side) and
hidden; left/right swaps (a joint nearer the other side's true joint, among those in plain view as their
other side and more than 5 COCO sigmas of s apart from it),
each beside the configured rate (twin.keypoint_errors; a limb's swap share: swap_rate x swap_frames / 3
limbs). Per camera: the share of frames with a false person, and of the players' joints missed, hidden
and swapped."""
RATES_CAPTION = """The rates beside the published evaluation they should come from. Ronchi & Perona 2017
class each keypoint of a detector's matched detection by its similarity ks = exp(-d^2 / (2 s^2 (2
sigma)^2)) to the true keypoints in the image (their released code, coco-analyze's
COCOanalyze._find_kpt_errors): good (its own, ks > 0.85), jitter (its own, 0.5 <= ks < 0.85), inversion
(the same person's left/right counterpart, ks >= 0.5), swap (another person's, ks >= 0.5), miss (ks < 0.5 to
every one; a keypoint a detector leaves out counts here). `twin_pct`: the players' COCO keypoints inside
the image, every camera and session, classed by those definitions on the twin's JSON; beside it the
twin's error each class maps to (their inversion is the twin's left/right swap, their miss its lost
joint) and the configured rates behind it. `published_pct`: the mean over the 17 COCO keypoints of the
per-keypoint probabilities PoseFix (Moon, Chang & Lee 2019, CVPR; its released main/gen_batch.py) draws
each class with, which its author took from Ronchi & Perona's statistics of the CMU (OpenPose) and G-RMI
detectors on COCO (a person with more than 10 annotated keypoints, not in a crowd). sigma_scale and
swap_rate are set to them (jitter 14 %, inversion 3.5 %); the twin's scene has no person near a player's
joints, so no swap; its misses lie near the published share."""
SOURCES = """Sources. COCO's per-keypoint sigmas: the COCO keypoint evaluation
(cocodataset.org/#keypoints-eval; pycocotools cocoeval.py: nose .026, eyes .025, ears .035, shoulders .079,
elbows .072, wrists .062, hips .107, knees .087, ankles .089), the RMS of human annotators' 2D error as a
share of s on 5,000 redundantly annotated images; a detector as accurate as the annotators' agreement has
sigma_scale 1. Ronchi M. R., Perona P. 2017 (ICCV, "Benchmarking and Error Diagnosis in Multi-Instance Pose
Estimation", arXiv 1707.05388; definitions from their code, github.com/matteorr/coco-analyze); Moon G.,
Chang J. Y., Lee K. M. 2019 (CVPR, "PoseFix: Model-agnostic General Human Pose Refinement Network",
github.com/mks0601/PoseFix_RELEASE, main/gen_batch.py synthesize_pose: the per-keypoint rates above). In
3D, Needham et al. 2021 (Sci Rep, doi:10.1038/s41598-021-00212-x, abstract) found OpenPose's multi-camera
joint centres 30-50 mm off marker-based ones at the hip and knee (systematic) and 1-15 mm at the ankle:
compare perception_accuracy.md's 3D joint error."""


def _session_bodies(people: pd.DataFrame) -> tuple[list[str], np.ndarray]:
    names, bodies = [], []
    for name, rows in people.groupby("person", sort=False):
        names.append(name)
        bodies.append(rows[list(truth.JOINT_COLUMNS)].to_numpy().reshape(-1, 25, 3))
    return names, np.stack(bodies)


def main(ctx):
    p, i = ctx.params, ctx.input
    errors = KeypointErrors.from_config(p["keypoint_errors"])
    rig = {c["name"]: Camera.from_dict(c) for c in read_json(i.rig, truth.RIG)["cameras"]}
    cams, per_camera = [], []
    n_cams = len(p["cams"])
    for k in range(len(p["sessions"])):
        names, bodies = _session_bodies(read_table(i.people[k], truth.PEOPLE))
        for c, cam in enumerate(p["cams"]):
            folder = i.openpose[k * n_cams + c]
            detections = tk.read_twin_keypoints(folder, f"{p['sessions'][k]}_{cam}", bodies.shape[1])
            per_camera.append(tk.camera_errors(rig[cam], detections, bodies, names))
            cams.append(cam)
    joints = pd.DataFrame(tk.joint_rows(per_camera, errors))
    cameras = pd.DataFrame(tk.camera_rows(cams, per_camera))
    published = pd.DataFrame(tk.ronchi_perona_rows(per_camera, errors))
    text = (f"# {TITLE}\n\n{CAPTION}\n\n{joints.to_markdown(index=False, floatfmt='.3g')}\n\n"
            f"Per camera, over every session:\n\n{cameras.to_markdown(index=False, floatfmt='.3g')}\n\n"
            f"{RATES_CAPTION}\n\n{published.to_markdown(index=False, floatfmt='.3g')}\n\n{SOURCES}\n")
    write_text_atomic(ctx.output.md, text)
    table = pd.concat([joints.assign(table="joints"), cameras.assign(table="cameras"),
                       published.assign(table="ronchi_perona")], ignore_index=True)
    write_text_atomic(ctx.output.csv, table.to_csv(index=False))
