"""``python -m mistyle.train.export SOURCE DEST``: strip a training checkpoint down to what inference needs."""

import sys

from .trainer import export_checkpoint

if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: python -m mistyle.train.export runs/cpu/final.pt mistyle/checkpoints/skpn_cpu.pt")
    print(export_checkpoint(sys.argv[1], sys.argv[2]))
