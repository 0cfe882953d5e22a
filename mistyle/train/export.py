"""``python -m mistyle.train.export SOURCE DEST``: strip a training checkpoint down to what inference needs."""

import sys

from ..model.checkpoint import export_checkpoint

if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python -m mistyle.train.export runs/cpu/final.pt mistyle/checkpoints/skpn_cpu.pt")
    try:
        print(export_checkpoint(sys.argv[1], sys.argv[2]))
    except (ValueError, OSError) as error:
        sys.exit(f"error: {error}")
