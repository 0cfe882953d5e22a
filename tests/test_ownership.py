"""mistyle never writes over, or deletes, a file it did not write, and one run owns an output at a time
(``mistyle.ownership``: the manifest, the lock, the staging folders)."""

import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from PIL import Image

from mistyle.files import write_vol
from mistyle.ownership import MANIFEST_FILE, foreign_files, is_owned, staged_directory, write_manifest
from mistyle.render_final import main

FAST = ["--res", "16", "--spp", "1", "--refine", "0"]


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory, tiny_checkpoint_factory):
    return tiny_checkpoint_factory(tmp_path_factory.mktemp("ckpt") / "tiny.pt")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory, blob_density):
    folder = tmp_path_factory.mktemp("inputs")
    write_vol(folder / "blob.vol", blob_density)
    np.save(folder / "puff.npy", blob_density)
    frames = folder / "frames"
    frames.mkdir()
    for index in range(2):
        np.save(frames / f"frame_{index:04d}.npy", np.roll(blob_density, index, axis=2))
    rng = np.random.default_rng(0)
    Image.fromarray((rng.random((32, 32, 3)) * 255).astype(np.uint8)).save(folder / "style.png")
    return folder


def render(checkpoint, *arguments) -> int:
    return main(["--checkpoint", str(checkpoint), *map(str, arguments)])


def contents(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------ the manifest
def test_the_manifest_proves_which_files_are_mistyles(tmp_path):
    folder = tmp_path / "out"
    (folder / "sub").mkdir(parents=True)
    (folder / "a.png").write_bytes(b"image")
    (folder / "sub" / "b.npy").write_bytes(b"grid")
    assert foreign_files(folder) == ["a.png", "sub/b.npy"] and not is_owned(folder)
    write_manifest(folder, "render")
    assert is_owned(folder) and foreign_files(folder) == []
    os.utime(folder / "a.png", ns=(1, 1))  # touched, same bytes: still ours
    assert is_owned(folder)
    (folder / "a.png").write_bytes(b"edited")  # a user's edit
    (folder / "NOTES.txt").write_text("mine")
    (folder / "empty").mkdir()
    assert foreign_files(folder) == ["NOTES.txt", "a.png", "empty/"]


# ------------------------------------------------------------------ --save-look
def test_save_look_replaces_only_a_look_and_only_with_overwrite(mi, checkpoint, inputs, tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    fit = ["--density", inputs / "blob.vol", "--style", inputs / "style.png", "--look-steps", "1"]
    for victim in (inputs / "style.png", inputs / "puff.npy", notes):
        before = victim.read_bytes()
        for extra in ([], ["--overwrite"]):
            assert render(checkpoint, *fit, "--save-look", victim, *extra) == 2
            assert "is not a mistyle look; mistyle replaces only its own files" in capsys.readouterr().err
            assert victim.read_bytes() == before
    look = tmp_path / "wave.look"
    assert render(checkpoint, *fit, "--save-look", look) == 0
    first = look.read_bytes()
    assert render(checkpoint, *fit, "--save-look", look) == 2
    assert "already exists; pass --overwrite" in capsys.readouterr().err and look.read_bytes() == first
    assert render(checkpoint, *fit, "--save-look", look, "--overwrite") == 0
    link = tmp_path / "linked.look"
    link.symlink_to(look)
    assert render(checkpoint, *fit, "--save-look", link, "--overwrite") == 2
    assert "is a symbolic link (to" in capsys.readouterr().err and link.is_symlink()


# ------------------------------------------------------------------ --overwrite
def test_overwrite_keeps_what_a_user_added_or_edited_in_a_render(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "out"
    arguments = ["--density", inputs / "blob.vol", "--style", inputs / "style.png", "--out", out, *FAST]
    assert render(checkpoint, *arguments) == 0 and is_owned(out)
    capsys.readouterr()
    (out / "NOTES.txt").write_text("client notes")
    (out / "comp").mkdir()
    (out / "comp" / "shot.nk").write_text("nuke script")
    before = contents(out)
    assert render(checkpoint, *arguments, "--overwrite") == 2
    error = capsys.readouterr().err
    assert "holds NOTES.txt, comp/shot.nk:" in error and "Move them out" in error and error.count("\n") == 1
    assert contents(out) == before
    (out / "NOTES.txt").unlink()
    (out / "comp" / "shot.nk").unlink()
    (out / "comp").rmdir()
    (out / "final.png").write_bytes(b"retouched by hand")
    assert render(checkpoint, *arguments, "--overwrite") == 2
    assert "holds final.png: mistyle did not write them, or they changed since" in capsys.readouterr().err
    (out / "final.png").unlink()
    assert render(checkpoint, *arguments, "--overwrite") == 0 and is_owned(out)


def test_a_users_own_report_json_does_not_make_a_folder_mistyles(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "analysis"
    out.mkdir()
    (out / "report.json").write_text('{"inputs": ["survey.csv"]}')
    (out / "data.csv").write_text("1,2,3")
    before = contents(out)
    arguments = ["--density", inputs / "blob.vol", "--style", inputs / "style.png", "--out", out, *FAST]
    assert render(checkpoint, *arguments, "--overwrite") == 2
    assert "it has no manifest" in capsys.readouterr().err and contents(out) == before


def test_a_batch_out_holding_a_users_files_is_refused(mi, checkpoint, inputs, tmp_path, capsys):
    out = tmp_path / "site"
    out.mkdir()
    (out / "index.html").write_text("<h1>my site</h1>")
    (out / "photo.jpg").write_bytes(b"jpeg")
    before = contents(out)
    batch = ["--density", inputs / "blob.vol", inputs / "puff.npy", "--style", inputs / "style.png", *FAST]
    assert render(checkpoint, *batch, "--out", out, "--overwrite") == 2
    assert "holds index.html, photo.jpg" in capsys.readouterr().err and contents(out) == before

    # A batch's own folder is mistyle's: rendered again with --overwrite, or resumed.
    mine = tmp_path / "batch"
    assert render(checkpoint, *batch, "--out", mine) == 0
    assert sorted(p.name for p in mine.iterdir()) == [MANIFEST_FILE, "blob__style", "index.html", "puff__style"]
    assert render(checkpoint, *batch, "--out", mine, "--overwrite") == 0
    (mine / "photo.jpg").write_bytes(b"jpeg")
    assert render(checkpoint, *batch, "--out", mine, "--overwrite") == 2
    assert "holds photo.jpg" in capsys.readouterr().err


# ------------------------------------------------------------------ one writer at a time
HOLDER = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from mistyle.ownership import staged_directory
    out, go = Path(sys.argv[1]), Path(sys.argv[2])
    with staged_directory(out) as staging:
        (staging / "albedo.npy").write_bytes(b"grid")
        print("staged", flush=True)
        while not go.exists():
            time.sleep(0.05)
    """
)
CONTENDER = textwrap.dedent(
    """
    import sys
    from mistyle.ownership import staged_directory
    try:
        with staged_directory(sys.argv[1]) as staging:
            (staging / "intruder.npy").write_bytes(b"x")
    except ValueError as error:
        print(error)
        sys.exit(2)
    """
)


def test_while_one_run_writes_an_output_three_more_are_refused_and_its_files_survive(tmp_path):
    out, go = tmp_path / "out", tmp_path / "go"
    holder = subprocess.Popen([sys.executable, "-c", HOLDER, str(out), str(go)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "staged"
        lock = tmp_path / ".out.lock"
        inode = lock.stat().st_ino
        staging = sorted(p.name for p in tmp_path.glob(".out.partial-*"))
        contenders = [
            subprocess.Popen([sys.executable, "-c", CONTENDER, str(out)], stdout=subprocess.PIPE, text=True)
            for _ in range(3)
        ]
        for contender in contenders:
            message = contender.communicate(timeout=60)[0]
            assert contender.returncode == 2 and "Another mistyle run is writing to" in message
            assert f"(pid {holder.pid} on " in message
        # The refused runs left the holder's lock and staging folder alone.
        assert lock.stat().st_ino == inode and sorted(p.name for p in tmp_path.glob(".out.partial-*")) == staging
        go.touch()
        assert holder.wait(timeout=60) == 0
    finally:
        holder.kill()
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST_FILE, "albedo.npy"] and is_owned(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["go", "out"]  # no lock, no staging left


def test_a_waiting_run_takes_the_lock_its_holder_removed(tmp_path):
    from mistyle.ownership import output_lock

    out = tmp_path / "out"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom mistyle.ownership import output_lock\n"
            "with output_lock(sys.argv[1]):\n    print('held', flush=True)\n    time.sleep(1.0)",
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "held"
    started = time.monotonic()
    with output_lock(out, wait=True):
        assert time.monotonic() - started > 0.3  # it waited for the holder
        assert (tmp_path / ".out.lock").exists()  # and holds the file that is there now
    assert holder.wait(timeout=30) == 0
    assert not (tmp_path / ".out.lock").exists()


def test_an_output_edited_while_a_run_renders_is_not_replaced(tmp_path):
    out = tmp_path / "out"
    with staged_directory(out) as staging:
        (staging / "a.npy").write_bytes(b"one")
    with pytest.raises(ValueError, match="holds NOTES.txt"):
        with staged_directory(out) as staging:
            (staging / "a.npy").write_bytes(b"two")
            (out / "NOTES.txt").write_text("added while the run rendered")
    assert (out / "a.npy").read_bytes() == b"one" and (out / "NOTES.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_output_another_run_finished_since_the_check_is_not_replaced_without_overwrite(tmp_path):
    out = tmp_path / "out"
    with staged_directory(out, keep=("render",)) as staging:  # nothing there yet
        (staging / "a.npy").write_bytes(b"first run")
    worked = []
    with pytest.raises(ValueError, match="written by another mistyle run after this one began; pass --overwrite"):
        with staged_directory(out, keep=("render",)) as staging:
            worked.append(True)
    assert not worked and (out / "a.npy").read_bytes() == b"first run"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with staged_directory(out) as staging:  # --overwrite
        (staging / "a.npy").write_bytes(b"second run")
    assert (out / "a.npy").read_bytes() == b"second run"


def test_an_out_that_links_to_a_folder_is_written_through_the_link(mi, checkpoint, inputs, tmp_path, capsys):
    target = tmp_path / "disk" / "shot"
    target.mkdir(parents=True)
    link = tmp_path / "out"
    link.symlink_to(target, target_is_directory=True)
    arguments = ["--density", inputs / "blob.vol", "--style", inputs / "style.png", "--out", link, *FAST]
    assert render(checkpoint, *arguments) == 0
    assert link.is_symlink() and is_owned(target) and (target / "final.png").is_file()
    assert render(checkpoint, *arguments) == 2 and "already holds a render" in capsys.readouterr().err
    assert render(checkpoint, *arguments, "--overwrite") == 0 and link.is_symlink() and is_owned(target)
    broken = tmp_path / "broken"
    broken.symlink_to(tmp_path / "nowhere")
    assert render(checkpoint, *arguments[:4], "--out", broken, *FAST) == 2
    error = capsys.readouterr().err
    assert "--out" in error and "broken symbolic link" in error and "Traceback" not in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken", "disk", "out"]


# ------------------------------------------------------------------ chunks and resumes keep their settings
def test_resume_and_chunks_refuse_other_render_settings(mi, checkpoint, inputs, tmp_path, capsys):
    batch = ["--density", inputs / "blob.vol", inputs / "puff.npy", "--style", inputs / "style.png"]
    out = tmp_path / "batch"
    assert render(checkpoint, *batch, "--out", out, *FAST) == 0
    assert render(checkpoint, *batch, "--out", out, "--resume", "--res", "24", "--spp", "1", "--refine", "0") == 2
    assert "was rendered with --res 16 and this run asks for 24" in capsys.readouterr().err

    look = tmp_path / "wave.look"
    fit = ["--density", inputs / "frames", "--style", inputs / "style.png", "--look-steps", "1", "--save-look", look]
    assert render(checkpoint, *fit) == 0
    chunked = tmp_path / "chunked"
    chunk = ["--density", inputs / "frames", "--look", look, "--out", chunked, "--spp", "1"]
    assert render(checkpoint, *chunk, "--frames", "0", "--res", "16") == 0
    before = contents(chunked)
    assert render(checkpoint, *chunk, "--frames", "1", "--res", "24") == 2
    assert "was rendered with --res 16 and this run asks for 24" in capsys.readouterr().err
    assert contents(chunked) == before
    assert render(checkpoint, *chunk, "--frames", "1", "--res", "16") == 0 and is_owned(chunked)
    (chunked / "NOTES.txt").write_text("mine")
    assert render(checkpoint, *chunk, "--frames", "1", "--res", "16") == 2
    assert "holds NOTES.txt" in capsys.readouterr().err and (chunked / "NOTES.txt").exists()


# ------------------------------------------------------------------ options that named the wrong thing
def test_huge_mix_weights_a_gif_style_folder_and_a_look_folder(mi, checkpoint, inputs, tmp_path, capsys):
    from mistyle.outputs import style_choices, style_files

    (choice,) = style_choices(None, ["a.png:1e308", "b.png:3e307"])
    assert [weight for _, weight in choice.parts] == pytest.approx([1 / 1.3, 0.3 / 1.3])
    gifs = tmp_path / "gifs"
    gifs.mkdir()
    Image.open(inputs / "style.png").save(gifs / "wave.gif")
    assert style_files(gifs) == [gifs / "wave.gif"]
    arguments = ["--density", inputs / "blob.vol", "--look", tmp_path, "--out", tmp_path / "out", *FAST]
    assert render(checkpoint, *arguments) == 2
    assert "is a folder; give a look file" in capsys.readouterr().err
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    arguments = ["--density", tmp_path / "loop", "--style", inputs / "style.png", "--out", tmp_path / "out", *FAST]
    assert render(checkpoint, *arguments) == 2
    assert "is a symbolic link loop" in capsys.readouterr().err


def test_the_api_saves_a_look_over_a_look_only(tmp_path, blob_density, checkpoint):
    import mistyle
    from mistyle.look import LookSettings

    look = mistyle.fit_look(
        blob_density, np.full((16, 16, 3), 0.5, np.float32), checkpoint=checkpoint, settings=LookSettings(steps=1)
    )
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(ValueError, match="is not a mistyle look; a look replaces only a look"):
        look.save(notes)
    assert notes.read_text() == "mine"
    look.save(tmp_path / "a.look")
    look.save(tmp_path / "a.look")  # a look over a look: the API's choice
