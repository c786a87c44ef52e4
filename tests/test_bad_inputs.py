"""A catalogue of named bad inputs: each is refused before any work with exit 2 and one line
on stderr that names what the user wrote (the key, the path or the option), no traceback,
and nothing created where the output would have gone.

The cases are written by hand from the recipe reference (``datasets/README.md``, the
experiment docs); the properties over random mutations are in ``test_fuzz_recipes.py`` and
``test_fuzz_files.py``.
"""

import pytest
from test_cli import TINY as TINY_RANGING

from phyloc.cli import main

LOCALIZATION = """
kind = "localization"
name = "loc"
seed = 1
[system]
n_subcarriers = 257
subcarrier_spacing_hz = 146.5e3
[network]
region_m = [60.0, 60.0]
[experiment]
scenarios = { c2 = "winner2_c2" }
agents = [4]
realizations = 1
methods = ["dipnet", "corr"]
inits = ["truth_free"]
cdf_agents = [4]
[ranging]
beta = 8.0
window_m = [0.0, 300.0]
[localization]
n_particles = 100
n_iterations = 2
"""

DATASET = """
kind = "dataset"
name = "d"
seed = 3
[system]
n_subcarriers = 65
[network]
n_agents = 3
region_m = [60.0, 60.0]
[channel]
scenario = "winner2_c2"
[dataset]
realizations = 2
shard_size = 1
"""

RANGING = TINY_RANGING  # test_cli's ranging recipe


def _sub(base, old, new):
    assert old in base, old
    return base.replace(old, new, 1)


# (name, recipe text, what the one line must name) — evaluated with `phyloc evaluate`
EVALUATE_RECIPES = [
    ("unknown-method", _sub(LOCALIZATION, '["dipnet", "corr"]', '["foo"]'), "foo"),
    ("numeric-method-name", _sub(LOCALIZATION, '["dipnet", "corr"]', "[0]"), "methods"),
    ("empty-method-list", _sub(LOCALIZATION, '["dipnet", "corr"]', "[]"), "methods"),
    ("one-agent-network", _sub(LOCALIZATION, "agents = [4]", "agents = [1]"), "agents"),
    ("no-network-size", _sub(LOCALIZATION, "agents = [4]", "agents = []"), "agents"),
    (
        "zero-realizations",
        _sub(LOCALIZATION, "realizations = 1", "realizations = 0"),
        "realizations",
    ),
    ("unknown-init", _sub(LOCALIZATION, '["truth_free"]', '["psychic"]'), "psychic"),
    ("unknown-scenario", _sub(LOCALIZATION, '"winner2_c2"', '"winner2_x"'), "winner2_x"),
    ("zero-particles", _sub(LOCALIZATION, "n_particles = 100", "n_particles = 0"), "n_particles"),
    (
        "negative-iterations",
        _sub(LOCALIZATION, "n_iterations = 2", "n_iterations = -1"),
        "n_iterations",
    ),
    ("zero-prior-std", LOCALIZATION + "prior_std_m = 0.0\n", "prior_std_m"),
    ("word-prior-std", LOCALIZATION + 'prior_std_m = "wide"\n', "prior_std_m"),
    ("bool-prior-std", LOCALIZATION + "prior_std_m = true\n", "prior_std_m"),
    ("zero-outlier-bound", LOCALIZATION + "outlier_nats = 0.0\n", "outlier_nats"),
    ("negative-model-error", LOCALIZATION + "model_error_m = -1.0\n", "model_error_m"),
    (
        "concentration-above-one",
        LOCALIZATION + "los_min_concentration = 1.5\n",
        "los_min_concentration",
    ),
    ("string-for-one-sided-start", LOCALIZATION + 'init_one_sided = "yes"\n', "init_one_sided"),
    ("number-for-one-sided-bound", LOCALIZATION + "one_sided = 3\n", "one_sided"),
    ("unknown-likelihood", LOCALIZATION + 'likelihood = "magic"\n', "likelihood"),
    ("unknown-exchange", LOCALIZATION + 'exchange = "gossip"\n', "exchange"),
    ("resample-threshold-above-one", LOCALIZATION + "resample_ess = 2.0\n", "resample_ess"),
    ("misspelt-localization-key", LOCALIZATION + "n_particle = 100\n", "n_particle"),
    (
        "per-method-zero-particles",
        LOCALIZATION + "[localization.corr]\nn_particles = 0\n",
        "n_particles",
    ),
    (
        "string-for-a-number",
        _sub(LOCALIZATION, "n_particles = 100", 'n_particles = "many"'),
        "n_particles",
    ),
    ("zero-beta", _sub(LOCALIZATION, "beta = 8.0", "beta = 0.0"), "beta"),
    ("reversed-window", _sub(LOCALIZATION, "[0.0, 300.0]", "[300.0, 0.0]"), "window_m"),
    (
        "unknown-range-variance",
        LOCALIZATION.replace("[ranging]\n", '[ranging]\nvariance = "guess"\n'),
        "variance",
    ),
    (
        "even-subcarrier-count",
        _sub(LOCALIZATION, "n_subcarriers = 257", "n_subcarriers = 256"),
        "n_subcarriers",
    ),
    (
        "negative-subcarrier-spacing",
        _sub(LOCALIZATION, "146.5e3", "-146.5e3"),
        "subcarrier_spacing_hz",
    ),
    (
        "nan-tx-power",
        _sub(LOCALIZATION, "[system]\n", "[system]\ntx_power_dbm = nan\n"),
        "tx_power_dbm",
    ),
    (
        "infinite-carrier",
        _sub(LOCALIZATION, "[system]\n", "[system]\ncarrier_frequency_hz = inf\n"),
        "carrier_frequency_hz",
    ),
    (
        "text-noise-figure",
        _sub(LOCALIZATION, "[system]\n", '[system]\nnoise_figure_db = "loud"\n'),
        "noise_figure_db",
    ),
    (
        "one-dimensional-region",
        _sub(LOCALIZATION, "region_m = [60.0, 60.0]", "region_m = [60.0]"),
        "region_m",
    ),
    (
        "negative-region",
        _sub(LOCALIZATION, "region_m = [60.0, 60.0]", "region_m = [-60.0, 60.0]"),
        "region_m",
    ),
    ("four-dimensional-network", _sub(LOCALIZATION, "[network]\n", "[network]\ndim = 4\n"), "dim"),
    (
        "negative-anchor-count",
        _sub(LOCALIZATION, "[network]\n", "[network]\nanchors = -1\n"),
        "anchors",
    ),
    (
        "zero-comm-range",
        _sub(LOCALIZATION, "[network]\n", "[network]\ncomm_range_m = 0.0\n"),
        "comm_range_m",
    ),
    ("unknown-motion-model", LOCALIZATION + '[network.motion]\nmodel = "teleport"\n', "teleport"),
    ("zero-snapshots", LOCALIZATION + "[network.motion]\nn_snapshots = 0\n", "n_snapshots"),
    ("negative-seed", _sub(LOCALIZATION, "seed = 1", "seed = -1"), "seed"),
    ("misspelt-seed", _sub(LOCALIZATION, "seed = 1", "sed = 1"), "seed"),
    ("unknown-kind", _sub(LOCALIZATION, '"localization"', '"dance"'), "dance"),
    ("unknown-section", LOCALIZATION + "[bogus]\nx = 1\n", "bogus"),
    (
        "section-that-is-a-value",
        "system = 5\n" + LOCALIZATION.replace("[system]\n", "[sys]\n"),
        "system",
    ),
    ("unknown-ranging-method", _sub(RANGING, '["corr", "sage"]', '["telepathy"]'), "telepathy"),
    ("zero-sage-paths", _sub(RANGING, "n_paths = 3", "n_paths = 0"), "ranging.sage.n_paths"),
    ("text-awgn-snr", _sub(RANGING, "[20, 30]", '"loud"'), "awgn_snr_db"),
    ("misspelt-sage-option", _sub(RANGING, "n_iter = 3", "n_iters = 3"), "n_iters"),
    ("negative-sage-sweeps", _sub(RANGING, "n_iter = 3", "n_iter = -1"), "ranging.sage.n_iter"),
    (
        "positive-los-threshold",
        _sub(RANGING, "n_iter = 3", "los_threshold_db = 3.0"),
        "los_threshold_db",
    ),
    ("unknown-corr-option", RANGING + "[ranging.corr]\nthreshold = 2\n", "ranging.corr.threshold"),
    ("negative-awgn-links", _sub(RANGING, "awgn_links = 60", "awgn_links = -1"), "awgn_links"),
    ("dataset-recipe-to-evaluate", DATASET, "phyloc generate"),
]

# the same for `phyloc generate RECIPE -o OUT.h5`
GENERATE_RECIPES = [
    (
        "zero-dataset-realizations",
        _sub(DATASET, "realizations = 2", "realizations = 0"),
        "realizations",
    ),
    ("zero-shard-size", _sub(DATASET, "shard_size = 1", "shard_size = 0"), "shard_size"),
    ("unknown-compression", DATASET + 'compression = "zip"\n', "compression"),
    ("unknown-channel-scenario", _sub(DATASET, '"winner2_c2"', '"winner2_x"'), "winner2_x"),
    (
        "unknown-ranging-mode",
        _sub(DATASET, "[channel]\n", '[channel]\nranging = "three_way"\n'),
        "ranging",
    ),
    (
        "negative-nlos-bias",
        _sub(DATASET, "[channel]\n", "[channel]\nnlos_bias_mean_s = -1.0\n"),
        "nlos_bias_mean_s",
    ),
    (
        "zero-oversampling",
        _sub(DATASET, "[system]\n", "[system]\noversampling = 0\n"),
        "oversampling",
    ),
    (
        "network-too-large-for-memory",
        _sub(DATASET, "n_agents = 3", "n_agents = 1000000000"),
        "network.n_agents",
    ),
    (
        "shard-too-large-for-memory",
        _sub(
            _sub(DATASET, "n_agents = 3", "n_agents = 300"),
            "realizations = 2",
            "realizations = 4000",
        ).replace("shard_size = 1", "shard_size = 4000"),
        "dataset.shard_size",
    ),
    ("evaluate-section-with-unknown-method", DATASET + '[experiment]\nmethods = ["foo"]\n', "foo"),
    (
        "evaluate-section-with-zero-particles",
        DATASET + "[localization]\nn_particles = 0\n",
        "n_particles",
    ),
    ("evaluate-section-with-zero-beta", DATASET + "[ranging]\nbeta = 0.0\n", "beta"),
    ("misspelt-dataset-key", DATASET + "shard_sise = 1\n", "shard_sise"),
    (
        "environment-height-on-winner2",
        _sub(DATASET, "[channel]\n", "[channel]\nh_e_m = 1.0\n"),
        "channel.h_e_m",
    ),
    (
        "negative-environment-height-tr38901",
        _sub(DATASET, 'scenario = "winner2_c2"', 'scenario = "tr38901_umi"\nh_e_m = -1.0'),
        "channel.h_e_m",
    ),
    (
        "negative-antenna-height-tr38901",
        _sub(DATASET, 'scenario = "winner2_c2"', 'scenario = "tr38901_umi"\nh_tx_m = -3.0'),
        "channel.h_tx_m",
    ),
    ("experiment-recipe-to-generate", LOCALIZATION, "dataset"),
]


def _one_line_naming(capsys, fragment):
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err and fragment in lines[0], err
    return lines[0]


@pytest.mark.parametrize(
    ("text", "fragment"), [c[1:] for c in EVALUATE_RECIPES], ids=[c[0] for c in EVALUATE_RECIPES]
)
def test_bad_recipe_refused_by_evaluate(tmp_path, capsys, text, fragment):
    recipe = tmp_path / "r.toml"
    recipe.write_text(text)
    out = tmp_path / "out"
    assert main(["evaluate", str(recipe), "--out", str(out)]) == 2
    _one_line_naming(capsys, fragment)
    assert not out.exists()


@pytest.mark.parametrize(
    ("text", "fragment"), [c[1:] for c in GENERATE_RECIPES], ids=[c[0] for c in GENERATE_RECIPES]
)
def test_bad_recipe_refused_by_generate(tmp_path, capsys, text, fragment):
    recipe = tmp_path / "r.toml"
    recipe.write_text(text)
    out = tmp_path / "d.h5"
    assert main(["generate", str(recipe), "-o", str(out)]) == 2
    _one_line_naming(capsys, fragment)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.toml"]  # nothing left behind


def _missing(tmp_path):
    return ["evaluate", str(tmp_path / "nowhere.toml")], "nowhere.toml"


def _directory(tmp_path):
    (tmp_path / "adir.toml").mkdir()
    return ["evaluate", str(tmp_path / "adir.toml")], "directory"


def _non_utf8(tmp_path):
    (tmp_path / "latin1.toml").write_bytes(LOCALIZATION.replace("loc", "l\xf6c").encode("latin-1"))
    return ["evaluate", str(tmp_path / "latin1.toml")], "UTF-8"


def _binary(tmp_path):
    (tmp_path / "blob.toml").write_bytes(bytes(range(256)) * 4)
    return ["evaluate", str(tmp_path / "blob.toml")], "blob.toml"


def _empty(tmp_path):
    (tmp_path / "empty.toml").write_text("")
    return ["evaluate", str(tmp_path / "empty.toml")], "kind"


def _toml_syntax(tmp_path):
    (tmp_path / "syntax.toml").write_text(LOCALIZATION.replace("seed = 1", "seed = = 1"))
    return ["evaluate", str(tmp_path / "syntax.toml")], "syntax.toml"


def _out_is_a_file(tmp_path):
    (tmp_path / "r.toml").write_text(RANGING)
    (tmp_path / "taken").write_text("mine")
    return ["evaluate", str(tmp_path / "r.toml"), "--out", str(tmp_path / "taken")], "taken"


def _json_exists(tmp_path):
    (tmp_path / "b.json").write_text("{}")
    return ["bench", "phy", "--json", str(tmp_path / "b.json")], "b.json"


def _missing_dataset(tmp_path):
    return ["evaluate", str(tmp_path / "gone.h5")], "gone.h5"


def _not_hdf5(tmp_path):
    (tmp_path / "fake.h5").write_text("not an HDF5 file")
    return ["info", str(tmp_path / "fake.h5")], "fake.h5"


def _unknown_channel(tmp_path):
    return ["channel-stats", "winner2_x"], "winner2_c2"


def _malformed_scheduler(tmp_path):
    (tmp_path / "d.toml").write_text(DATASET)
    argv = ["generate", str(tmp_path / "d.toml"), "-o", str(tmp_path / "d.h5")]
    return [*argv, "--scheduler", "not a scheduler"], "scheduler"


def _generate_over_existing(tmp_path):
    (tmp_path / "d.toml").write_text(DATASET)
    (tmp_path / "d.h5").write_text("someone's file")
    return ["generate", str(tmp_path / "d.toml"), "-o", str(tmp_path / "d.h5")], "d.h5"


def _deep_dotted_key(tmp_path):
    key = ".".join(["a"] * 3000)
    (tmp_path / "deep.toml").write_text(LOCALIZATION + f"{key} = 1\n")
    return ["evaluate", str(tmp_path / "deep.toml")], "a.a.a…"


def _deep_arrays(tmp_path):
    (tmp_path / "nest.toml").write_text(LOCALIZATION + "x = " + "[" * 5000 + "]" * 5000 + "\n")
    return ["evaluate", str(tmp_path / "nest.toml")], "too deeply"


def _npz_header_claims_petabytes(tmp_path):
    """An .npz whose array header claims 10^15 float64 (a valid header, 24 bytes of data)."""
    import io
    import zipfile

    import numpy as np

    buf = io.BytesIO()
    header = {"descr": "<f8", "fortran_order": False, "shape": (10**15,)}
    np.lib.format.write_array_header_1_0(buf, header)
    buf.write(np.zeros(3).tobytes())
    with zipfile.ZipFile(tmp_path / "huge.npz", "w") as z:
        z.writestr("waveforms.npy", buf.getvalue())
    return ["import", str(tmp_path / "huge.npz"), "-o", str(tmp_path / "o.h5")], "waveforms"


def _h5_dataset_beyond_memory(tmp_path):
    """A plain HDF5 file declaring a 2^50-element dataset (no data written: HDF5 allocates
    lazily, so the file is small)."""
    import h5py

    with h5py.File(tmp_path / "big.h5", "w") as f:
        f.create_dataset("waveforms", shape=(2**50,), dtype="f8", chunks=(1024,))
    return ["import", str(tmp_path / "big.h5"), "-o", str(tmp_path / "o.h5")], "memory"


def _json_under_a_file(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    target = tmp_path / "notes.txt" / "stats.json"
    return ["channel-stats", "winner2_c2", "--links", "50", "--json", str(target)], "notes.txt"


def _json_is_a_folder(tmp_path):
    (tmp_path / "out").mkdir()
    return ["analyze", "belief-shift", "--json", str(tmp_path / "out")], "folder"


def _deep_channel_file(tmp_path):
    (tmp_path / "deep_channel.toml").write_text(".".join(["a"] * 3000) + " = 1\n")
    return ["channel-stats", str(tmp_path / "deep_channel.toml")], "deep_channel.toml"


def _tdl_negative_delay_spread(tmp_path):
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "channels" / "tdl_a.toml").read_text()
    import re

    bad = re.sub(r"(?m)^delay_spread_s\s*=\s*[^#\n]+", "delay_spread_s = -1.0e-7 ", text, count=1)
    assert bad != text
    (tmp_path / "my_tdl.toml").write_text(bad)
    return ["channel-stats", str(tmp_path / "my_tdl.toml"), "--links", "50"], "delay_spread_s"


def _channel_compare_zero_links(tmp_path):
    return ["channel-compare", "tr38901_umi", "--links", "0"], "--links"


def _channel_compare_winner2(tmp_path):
    return ["channel-compare", "winner2_c2", "--links", "100"], "winner2_c2"


def _channel_compare_frequency_beyond_the_tables(tmp_path):
    args = ["channel-compare", "tr38901_umi", "--carrier-frequency-hz", "1e12"]
    return [*args, "--png", str(tmp_path / "c.png")], "--carrier-frequency-hz"


def _cci_of_an_nlos_only_channel(tmp_path):
    return ["analyze", "cci", "tdl_a", "--links", "0", "--png", str(tmp_path / "c.png")], "tdl_a"


def _recipe_scenario_file_outside_its_folder(tmp_path):
    (tmp_path / "chan.toml").write_text("model = 'awgn'\n")
    (tmp_path / "r").mkdir()
    recipe = tmp_path / "r" / "d.toml"
    recipe.write_text(_sub(DATASET, 'scenario = "winner2_c2"', 'scenario = "../chan.toml"'))
    return ["generate", str(recipe), "-o", str(tmp_path / "r" / "d.h5")], "channel.scenario"


FILE_CASES = [
    ("channel-compare-winner2", _channel_compare_winner2),
    ("channel-compare-frequency-beyond-tables", _channel_compare_frequency_beyond_the_tables),
    ("cci-of-an-nlos-only-channel", _cci_of_an_nlos_only_channel),
    ("recipe-scenario-file-outside-its-folder", _recipe_scenario_file_outside_its_folder),
    ("tdl-file-negative-delay-spread", _tdl_negative_delay_spread),
    ("channel-compare-zero-links", _channel_compare_zero_links),
    ("channel-file-3000-levels-deep", _deep_channel_file),
    ("channel-stats-json-under-a-file", _json_under_a_file),
    ("belief-shift-json-is-a-folder", _json_is_a_folder),
    ("npz-header-claims-petabytes", _npz_header_claims_petabytes),
    ("hdf5-dataset-beyond-memory", _h5_dataset_beyond_memory),
    ("recipe-key-3000-levels-deep", _deep_dotted_key),
    ("recipe-arrays-5000-levels-deep", _deep_arrays),
    ("missing-recipe", _missing),
    ("recipe-is-a-directory", _directory),
    ("recipe-not-utf8", _non_utf8),
    ("recipe-binary", _binary),
    ("recipe-empty", _empty),
    ("recipe-toml-syntax", _toml_syntax),
    ("out-is-a-file", _out_is_a_file),
    ("bench-json-exists", _json_exists),
    ("missing-dataset", _missing_dataset),
    ("dataset-not-hdf5", _not_hdf5),
    ("unknown-channel-scenario-name", _unknown_channel),
    ("malformed-scheduler-address", _malformed_scheduler),
    ("generate-over-an-existing-file", _generate_over_existing),
]


@pytest.mark.parametrize("case", [c[1] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_file_or_option_refused(tmp_path, capsys, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    argv, fragment = case(tmp_path)
    before = {p: (p.read_bytes() if p.is_file() else None) for p in tmp_path.rglob("*")}
    assert main(argv) == 2
    _one_line_naming(capsys, fragment)
    after = {p: (p.read_bytes() if p.is_file() else None) for p in tmp_path.rglob("*")}
    assert after == before  # nothing created, nothing changed


def test_the_catalogue_has_at_least_sixty_named_cases():
    names = [c[0] for c in EVALUATE_RECIPES + GENERATE_RECIPES + FILE_CASES]
    assert len(names) == len(set(names)) >= 60


def test_shipped_recipes_nest_well_within_the_limit():
    """Every shipped recipe loads, and its deepest table or array is far from the nesting
    limit that refuses crafted recipes (a limit that a real recipe would meet is a defect)."""
    import tomllib
    from pathlib import Path

    from phyloc.config import MAX_DEPTH, load_recipe

    def depth(x):
        if isinstance(x, dict):
            return 1 + max(map(depth, x.values()), default=0)
        if isinstance(x, list):
            return 1 + max(map(depth, x), default=0)
        return 0

    recipes = sorted((Path(__file__).resolve().parents[1] / "datasets").glob("*.toml"))
    assert len(recipes) > 20
    deepest = max(depth(tomllib.loads(r.read_text())) for r in recipes)
    assert all(load_recipe(r).name for r in recipes)
    assert 3 <= deepest <= MAX_DEPTH // 2
