"""`make figures`: the README's figures drawn from a profile's run, each small enough for the
repository, and the committed ones the ones the README shows."""

import json
import re
from pathlib import Path

import numpy as np
from PIL import Image

from dgt_lib.app import figures

ROOT = Path(__file__).resolve().parent.parent


def test_the_committed_figures_are_small_and_every_one_is_shown():
    committed = sorted(p.name for p in figures.OUT.glob("*.png"))
    source = (figures.OUT / "README.md").read_text()
    by_scripts = re.findall(r"- \[`(\w+\.png)`\]\(\1\): `[^`]*python [^`]+`",
                            source.split(figures.SCRIPTS_SECTION)[1])  # each with its command
    assert committed == sorted([f"{name}.png" for name in figures.FIGURES] + by_scripts)
    assert [p.name for p in figures.OUT.glob("*.png") if p.stat().st_size > figures.MAX_BYTES] == []
    shown = set(re.findall(r"figures/(\w+\.png)", "\n".join(
        p.read_text() for p in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")])))
    assert shown == set(committed)
    assert re.search(r"--profile \w+ --seed \d+` from the `\w+` profile's run seed \d+, "
                     r"with the code at commit `\w+", source)


def test_a_figure_too_large_is_saved_with_a_palette_that_keeps_its_colours(tmp_path):
    import matplotlib.pyplot as plt

    def draw():
        fig, ax = plt.subplots(figsize=(4, 3))
        ax.imshow(np.linspace(0, 1, 400).reshape(20, 20), cmap="magma")
        return fig

    fig = draw()
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    plain = figures.save_png(fig, tmp_path / "plain.png", dpi=fig.dpi)
    assert Image.open(plain).mode == "RGBA"
    small = figures.save_png(draw(), tmp_path / "small.png", dpi=fig.dpi,
                             max_bytes=plain.stat().st_size - 1)
    image = Image.open(small)
    assert image.mode == "P" and small.stat().st_size < plain.stat().st_size
    assert np.abs(np.asarray(image.convert("RGB")).astype(int) - rgb).max() <= 4


def test_make_figures_draws_every_figure_of_the_smoke_run(tmp_path):
    """On the smoke run in the kit's data directory: what it lacks is built there, as
    `dgt reproduce --profile smoke` would (the step of `make test` after the unit tests,
    which then finds it cached); the figures go to a temporary folder."""
    kept = f"{figures.SCRIPTS_SECTION}\n\n- [`study.png`](study.png): `python studies/x.py`\n"
    (tmp_path / "README.md").write_text(f"# Figures\n\nDrawn by an older kit.\n\n{kept}")
    paths = figures.make_figures("smoke", tmp_path)
    assert sorted(p.name for p in paths) == sorted(f"{n}.png" for n in figures.FIGURES)
    for path in paths:
        assert 3_000 < path.stat().st_size <= figures.MAX_BYTES, path.name
        assert Image.open(path).size[0] >= 400
    text = (tmp_path / "README.md").read_text()
    assert "`smoke` profile's run seed 0" in text
    assert text.endswith("\n\n" + kept) and "older kit" not in text  # the studies' list stays
    facts = json.loads((tmp_path / figures.FACTS).read_text())  # what the README's caption says
    assert (facts["profile"], facts["seed"]) == ("smoke", 0) and facts["processor"]["cpus"]
    assert set(facts["hero_routes"]) == {"ascent", "descent", "jeep", "mercedes_van"}
    assert {facts["hero_routes"][k] for k in ("jeep", "mercedes_van")} <= {
        "sharp", "smooth", "no path"}
    assert all(f"[`{p.name}`]({p.name})" in text for p in paths)
