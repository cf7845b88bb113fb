"""The imports of the jobs that read camera streams (detection, pose2d, sync_check: 36 of a default run's
141), with PyAV imported up front as `pingpong.io.camera_streams` did before 7cd0a29, against now (PyAV
imported only where a video file is read), in fresh Python processes, alternated.

    PYTHONPATH=src python benchmarks/bench_job_start.py [--runs 7]
"""

import argparse

from timing import fresh_process_medians

STAGES = "import pingpong.stages.detection, pingpong.stages.pose2d, pingpong.stages.sync_check"
SIDES = {"PyAV imported up front (before 7cd0a29)": "import av\n" + STAGES,
         "PyAV imported where a video is read": STAGES + "\nimport sys\nassert 'av' not in sys.modules"}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    a = ap.parse_args()
    medians = fresh_process_medians(SIDES, a.runs)
    baseline, ours = medians.values()
    print(f"| imports of the three stages (median of {a.runs}) | s |\n|---|---:|")
    for name, s in medians.items():
        print(f"| {name} | {s:.2f} |")
    print(f"| saved a job | {baseline - ours:.2f} s |")


if __name__ == "__main__":
    main()
