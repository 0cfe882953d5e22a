"""``python -m mistyle.train.export SOURCE [SOURCE ...] DEST``: an inference checkpoint.

One source: strip a training checkpoint down to what inference needs. Several: the average of their
weights (checkpoints of one run along its trajectory, stochastic weight averaging), with the last
one's config and step; they must share the architecture and the extractor.

Options (one source): ``--set section.key=value`` changes a setting in the stored config that leaves
the weights as they are; ``--half`` stores float16 weights.
"""

import sys

from ..model.checkpoint import average_checkpoints, export_checkpoint

USAGE = (
    "usage: python -m mistyle.train.export runs/cpu/final.pt mistyle/checkpoints/skpn_cpu.pt\n"
    "       python -m mistyle.train.export runs/cpu/steps/step_001500.pt runs/cpu/steps/step_002000.pt averaged.pt\n"
    "       python -m mistyle.train.export --set section.key=value --half SOURCE DEST"
)


def main(argv: list[str]) -> str:
    overrides, half, paths = [], False, []
    arguments = iter(argv)
    for argument in arguments:
        if argument == "--set":
            overrides.append(next(arguments, ""))
        elif argument == "--half":
            half = True
        else:
            paths.append(argument)
    if len(paths) < 2:
        raise SystemExit(USAGE)
    sources, destination = paths[:-1], paths[-1]
    if len(sources) > 1 and (overrides or half):
        raise SystemExit("error: --set and --half take one source; average first, then export the average.\n" + USAGE)
    try:
        return str(
            export_checkpoint(sources[0], destination, overrides, half)
            if len(sources) == 1
            else average_checkpoints(sources, destination)
        )
    except (ValueError, OSError) as error:
        raise SystemExit(f"error: {error}") from None


if __name__ == "__main__":
    print(main(sys.argv[1:]))
