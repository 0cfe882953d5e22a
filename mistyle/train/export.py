"""``python -m mistyle.train.export SOURCE [SOURCE ...] DEST``: an inference checkpoint.

One source: strip a training checkpoint down to what inference needs. Several: the average of their
weights (checkpoints of one run along its trajectory, stochastic weight averaging), with the last
one's config and step; they must share the architecture and the extractor.
"""

import sys

from ..model.checkpoint import average_checkpoints, export_checkpoint

USAGE = ("usage: python -m mistyle.train.export runs/cpu/final.pt mistyle/checkpoints/skpn_cpu.pt\n"
         "       python -m mistyle.train.export runs/cpu/steps/step_001500.pt runs/cpu/steps/step_002000.pt averaged.pt")

if __name__ == "__main__":
    if len(sys.argv) < 3:
        sys.exit(USAGE)
    sources, destination = sys.argv[1:-1], sys.argv[-1]
    try:
        print(export_checkpoint(sources[0], destination) if len(sources) == 1 else average_checkpoints(sources, destination))
    except (ValueError, OSError) as error:
        sys.exit(f"error: {error}")
