"""Channel scenarios: the TOML files of ``channels/`` and their validating loader.

A scenario file (schema ``"phyloc.channel.v1"``) holds metadata, the carrier-frequency range,
the LOS-probability law and one parameter table per propagation condition, ``[los]`` and/or
``[nlos]`` (file layout and key list: ``channels/README.md``). Five models exist:

``winner2``
    WINNER II generic model (D1.1.2 Part I, Sec. 4.2): path loss + shadowing, log-normal delay
    spread, normal K-factor (dB), exponential (or uniform) cluster delays, cluster powers with
    per-cluster shadowing, sub-cluster split of the two strongest clusters.
``exponential``
    The LOS/NLOS model of DiPNet's analysis (§IV-A, Appendix III): excess delays
    ``δ_l ~ Exp`` with mean ``excess_delay_mean_s``, a Poisson number of paths, a fixed
    LOS-to-scatter power ratio, NLOS bias ``b ~ Exp``.
``awgn``
    A single LOS path with free-space loss (DiPNet §V-A benchmark).
``field``
    An open field with physically stated paths (:mod:`phyloc.channels.field`): the free-space
    direct path, the ground reflection with the Fresnel coefficient of the ground (two-ray),
    specular paths of metallic structures and an exponential diffuse tail. LOS only.
``tdl``
    The tapped delay lines TDL-A to TDL-E of 3GPP TR 38.901 (:mod:`phyloc.channels.tdl`):
    tabulated taps scaled to a delay spread, Rayleigh taps and, in TDL-D/E, a specular first
    tap; a path-loss law from the file (the shipped files: free space).
``tr38901``
    The system-level scenarios of 3GPP TR 38.901 Sec. 7.4–7.5 in the delay domain
    (:mod:`phyloc.channels.tr38901`): LOS probability, path loss and shadowing with the
    tables' own laws, DS/K/SF with cross-correlation, clusters with sub-clusters.

Names. Shipped files are found with ``importlib.resources.files("phyloc.scenarios")``. A file
``<base>_los.toml`` / ``<base>_nlos.toml`` provides the names ``<base>_los`` / ``<base>_nlos``
(condition forced) and, if both exist, ``<base>`` (condition drawn per link from P_LOS(d)). A
file ``<base>.toml`` with both sections provides ``<base>``, ``<base>_los`` and ``<base>_nlos``.
Anything else that names an existing file is loaded as a user scenario file.

References
----------
WINNER II: IST-4-027756 WINNER II Deliverable D1.1.2 V1.2, Part I (channel models), 2007,
updated 2008; the table each value of the shipped channel files comes from is given in
``channels/PROVENANCE.md``.

DiPNet: S. Zhang, E. Staudinger, T. Jost, W. Wang, C. Gentner, A. Dammann, H. Wymeersch and
P. A. Hoeher, "Distributed direct localization suitable for dense networks," IEEE Trans.
Aerospace and Electronic Systems 56(2), pp. 1209–1227, 2020.
"""

from __future__ import annotations

import functools
import importlib.resources
import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from phyloc.channels import _schema as s
from phyloc.channels.pathloss import LosProbability, PathLoss
from phyloc.channels.tdl import parse_tdl_condition
from phyloc.channels.tr38901 import parse_tr38901
from phyloc.errors import ValidationError

SCHEMA = "phyloc.channel.v1"
MODELS = ("winner2", "exponential", "awgn", "field", "tdl", "tr38901")
CONDITIONS = ("los", "nlos")

#: Default mean NLOS bias [s]: DiPNet §V-A (GREAT ray tracing, urban).
DEFAULT_NLOS_BIAS_MEAN_S = 0.3e-6

_TOP = {
    "schema": s.Choice((SCHEMA,)),
    "name": s.Text(),
    "model": s.Choice(MODELS),
    "title": s.Text(default=""),
    "source": s.Text(),
    "notes": s.TextList(),
    "validity": {"carrier_frequency_hz": s.Vec(s.Num(0.0, 1.0e12, lo_open=True), n=2)},
    "los_probability": s.Raw(),  # checked by LosProbability.from_table
    "los": s.Raw(default=None),  # checked per model
    "nlos": s.Raw(default=None),
}

_CORR = s.Num(-1.0, 1.0, default=0.0)
_BIAS = s.Num(0.0, 1.0e-4, default=DEFAULT_NLOS_BIAS_MEAN_S)


def _winner2_spec(condition: str, delay_distribution: str) -> dict:
    lsp = {
        "ds_log10_s_mu": s.Num(-10.0, -4.0),
        "ds_log10_s_sigma": s.Num(0.0, 3.0),
        "cross_correlation": {"ds_sf": _CORR},
    }
    clusters = {
        "num_clusters": s.Num(1, 100, integer=True),
        "delay_distribution": s.Choice(("exponential", "uniform")),
        "cluster_shadowing_std_db": s.Num(0.0, 30.0),
    }
    if delay_distribution == "uniform":
        clusters["uniform_delay_max_s"] = s.Num(0.0, 1.0e-4, lo_open=True)
    else:
        clusters["r_tau"] = s.Num(1.0, 20.0)
    spec = {"pathloss": s.Raw()}
    if condition == "los":
        lsp["k_factor_db_mu"] = s.Num(-30.0, 40.0)
        lsp["k_factor_db_sigma"] = s.Num(0.0, 20.0)
        lsp["cross_correlation"] = {"ds_sf": _CORR, "ds_k": _CORR, "sf_k": _CORR}
        clusters["los_delay_scaling"] = s.Vec(s.Num(-10.0, 10.0), n=4)
    else:
        spec["nlos_bias_mean_s"] = _BIAS
    spec["lsp"] = lsp
    spec["clusters"] = clusters
    spec["subclusters"] = {
        "num_split": s.Num(0, 100, integer=True),
        "delay_offsets_s": s.Vec(s.Num(0.0, 1.0e-6)),
        "power_fractions": s.Vec(s.Num(0.0, 1.0, lo_open=True)),
    }
    return spec


def _exponential_spec(condition: str) -> dict:
    spec = {
        "pathloss": s.Raw(),
        "excess_delay_mean_s": s.Num(0.0, 1.0e-4, lo_open=True),
        "mean_path_count": s.Num(1.0, 1000.0),
    }
    if condition == "los":
        spec["los_to_scatter_power_db"] = s.Num(-50.0, 50.0)
    else:
        spec["nlos_bias_mean_s"] = _BIAS
    return spec


_FIELD_SPEC = {
    "ground": {
        "reflection": s.Flag(default=True),
        "polarization": s.Choice(("vertical", "horizontal")),
        "permittivity_a": s.Num(1.0, 100.0),
        "permittivity_b": s.Num(-2.0, 2.0),
        "conductivity_c_s_m": s.Num(0.0, 100.0),
        "conductivity_d": s.Num(-3.0, 3.0),
    },
    "scatterers": {
        "count": s.Num(0, 100, integer=True),
        "excess_delay_min_s": s.Num(0.0, 1.0e-5),
        "excess_delay_max_s": s.Num(0.0, 1.0e-5),
        "reflection_loss_db": s.Num(0.0, 100.0),
    },
    "diffuse": {
        "ray_count": s.Num(0, 1000, integer=True),
        "delay_spread_s": s.Num(0.0, 1.0e-5, lo_open=True),
        "power_ratio_db": s.Num(-100.0, 30.0),
    },
}


# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Winner2Condition:
    """WINNER II parameters of one condition (WINNER II D1.1.2 Tables 4-4, 4-5; Sec. 4.2).

    Attributes
    ----------
    condition : {"los", "nlos"}
    pathloss : PathLoss
        Path-loss law and shadow-fading std (WINNER II D1.1.2 Table 4-4).
    ds_log10_mu, ds_log10_sigma : float
        Mean / std of ``log10(DS / 1 s)`` (WINNER II D1.1.2 Table 4-5).
    k_db_mu, k_db_sigma : float
        Ricean K-factor mean / std [dB] (LOS; NaN in NLOS).
    correlation : [n_lsp, n_lsp] float64
        Correlation of the standard-normal LSP draws ``[DS, SF(, K)]`` (WINNER II D1.1.2 Table 4-5).
    cholesky : [n_lsp, n_lsp] float64
        Lower Cholesky factor of ``correlation``.
    num_clusters : int
        N.
    delay_distribution : {"exponential", "uniform"}
    r_tau : float
        Delay proportionality factor (exponential delays).
    uniform_delay_max_s : float
        Upper limit of uniform delays [s] (B1 NLOS).
    cluster_shadowing_std_db : float
        Per-cluster shadowing ζ [dB].
    los_delay_scaling : tuple of 4 float
        ``c0..c3`` of ``D(K)`` (WINNER II eq. (4.3)), LOS only.
    num_split : int
        Number of strongest clusters split into sub-clusters (step 11).
    subcluster_offsets_s, subcluster_fractions : tuple of float
        Delay offsets [s] and power fractions of the sub-clusters.
    nlos_bias_mean_s : float
        Mean of the NLOS bias ``b`` [s] (0 in LOS).
    """

    condition: str
    pathloss: PathLoss
    ds_log10_mu: float
    ds_log10_sigma: float
    k_db_mu: float
    k_db_sigma: float
    correlation: np.ndarray
    cholesky: np.ndarray
    num_clusters: int
    delay_distribution: str
    r_tau: float
    uniform_delay_max_s: float
    cluster_shadowing_std_db: float
    los_delay_scaling: tuple
    num_split: int
    subcluster_offsets_s: tuple
    subcluster_fractions: tuple
    nlos_bias_mean_s: float

    @property
    def paths_per_link(self) -> int:
        """Paths of one link: clusters, extra sub-clusters and (LOS) the direct path."""
        extra = self.num_split * (len(self.subcluster_offsets_s) - 1)
        return self.num_clusters + extra + (self.condition == "los")


@dataclass(frozen=True, eq=False)
class ExponentialCondition:
    """DiPNet analysis-model parameters of one condition (DiPNet §IV-A, Appendix III).

    Attributes
    ----------
    condition : {"los", "nlos"}
    pathloss : PathLoss
    excess_delay_mean_s : float
        Mean of ``δ_l ~ Exp`` [s] (``1/a_L`` in LOS, ``1/a_N`` in NLOS: DiPNet uses rates).
    mean_path_count : float
        Mean number of multipath components ``L̄`` (LOS path not counted);
        ``L = 1 + Poisson(L̄ − 1)``.
    k_db : float
        LOS-to-scatter power ratio [dB] (LOS; NaN in NLOS).
    nlos_bias_mean_s : float
        Mean of ``b ~ Exp`` [s] (``1/a_B``; 0 in LOS).
    """

    condition: str
    pathloss: PathLoss
    excess_delay_mean_s: float
    mean_path_count: float
    k_db: float
    nlos_bias_mean_s: float


@dataclass(frozen=True, eq=False)
class AwgnCondition:
    """A single LOS path with the given path-loss law."""

    condition: str
    pathloss: PathLoss
    nlos_bias_mean_s: float = 0.0


@dataclass(frozen=True, eq=False)
class FieldCondition:
    """Parameters of the ``field`` model (LOS only; equations in :mod:`phyloc.channels.field`).

    Attributes
    ----------
    condition : {"los"}
    polarization : {"vertical", "horizontal"}
        Polarization of both antennas, which selects the Fresnel coefficient of the ground.
    permittivity_a, permittivity_b : float
        Relative permittivity of the ground ``ε_r = a·(f / 1 GHz)^b``.
    conductivity_c_s_m, conductivity_d : float
        Conductivity of the ground ``σ = c·(f / 1 GHz)^d`` [S/m].
    scatterer_count : int
        Specular paths of metallic structures per link, ``K_s``.
    scatterer_excess_delay_s : (float, float)
        Their excess delays are uniform on this interval [s].
    scatterer_reflection_loss_db : float
        Reflection loss of a structure [dB]; the path's amplitude is
        ``10^(−loss/20)·λ/(4π L)`` with its unfolded length ``L = d + c0·τ_excess``.
    diffuse_ray_count : int
        Diffuse rays per link, ``N_d``.
    diffuse_delay_spread_s : float
        Mean (= rms spread) of their exponential excess delays [s].
    diffuse_power_ratio_db : float
        Total diffuse power relative to the free-space power of the direct path [dB].
    nlos_bias_mean_s : float
        Always 0 (no NLOS part).
    ground_reflection : bool
        ``[los.ground] reflection`` (default true). False gives the ground-reflected path zero
        power and changes nothing else: the same random draws give the same other paths, so
        runs with and without it are paired (the cause of a difference isolated).
    """

    condition: str
    polarization: str
    permittivity_a: float
    permittivity_b: float
    conductivity_c_s_m: float
    conductivity_d: float
    scatterer_count: int
    scatterer_excess_delay_s: tuple
    scatterer_reflection_loss_db: float
    diffuse_ray_count: int
    diffuse_delay_spread_s: float
    diffuse_power_ratio_db: float
    nlos_bias_mean_s: float = 0.0
    ground_reflection: bool = True

    @property
    def paths_per_link(self) -> int:
        """Paths of one link: direct, ground reflection, scatterers and diffuse rays."""
        return 2 + self.scatterer_count + self.diffuse_ray_count


@dataclass(frozen=True, eq=False)
class Scenario:
    """A validated channel scenario.

    Attributes
    ----------
    name : str
        Scenario name (``winner2_c2``, ``winner2_c2_los``, ``awgn``, a user file's name...).
    model : {"winner2", "exponential", "awgn", "field", "tdl", "tr38901"}
    los_probability : LosProbability or Tr38901LosProbability
        P_LOS(d) (WINNER II D1.1.2 Table 4-7; TR 38.901 Table 7.4.2-1).
    los, nlos : condition parameters or None
        Parameters per condition; a missing one cannot be drawn.
    forced : {"los", "nlos"} or None
        The condition every link gets; ``None`` draws it from P_LOS(d).
    carrier_frequency_range_hz : (float, float)
        Frequencies the path-loss laws are valid for [Hz].
    source : str
        The table(s) the numbers come from.
    files : tuple of str
        The files loaded.
    """

    name: str
    model: str
    los_probability: LosProbability
    los: object
    nlos: object
    forced: str | None
    carrier_frequency_range_hz: tuple
    source: str
    files: tuple

    def params(self, condition: str):
        """Parameters of ``"los"`` or ``"nlos"``; error if the scenario lacks them."""
        p = self.los if condition == "los" else self.nlos
        if p is None:
            raise ValidationError(
                "condition", condition, f"scenario '{self.name}' has no {condition.upper()} part"
            )
        return p

    def p_los(self, distances_m, h_bs_m=1.5, h_ut_m=1.5) -> np.ndarray:
        """Probability that a link is LOS in this scenario (1/0 when the condition is forced).

        ``h_bs_m``, ``h_ut_m`` (higher and lower antenna height [m]) enter only the tr38901
        laws (TR 38.901 Table 7.4.2-1: the 2D distance, UMa's ``h_UT`` term, InF-SH/DH).
        """
        d = np.asarray(distances_m, dtype=np.float64)
        if self.forced is not None:
            return np.full(d.shape, 1.0 if self.forced == "los" else 0.0)
        if self.model == "tr38901":
            return self.los_probability(d, h_bs_m, h_ut_m)
        return self.los_probability(d)

    def with_condition(self, condition: str | None) -> Scenario:
        """The same scenario with the condition forced (``None``: drawn from P_LOS)."""
        if condition is not None:
            self.params(condition)
        elif self.los is None or self.nlos is None:
            return self
        if condition == self.forced:
            return self
        name = _base_name(self.name) + ("" if condition is None else f"_{condition}")
        return Scenario(
            name,
            self.model,
            self.los_probability,
            self.los,
            self.nlos,
            condition,
            self.carrier_frequency_range_hz,
            self.source,
            self.files,
        )

    def check_frequency(self, fc_hz: float) -> None:
        """Raise :class:`ValidationError` if ``fc_hz`` is outside the validity range."""
        lo, hi = self.carrier_frequency_range_hz
        if not lo <= fc_hz <= hi:
            raise ValidationError(
                "system.carrier_frequency_hz",
                fc_hz,
                f"scenario '{self.name}' is valid for [{lo:g}, {hi:g}] Hz "
                f"(edit validity.carrier_frequency_hz in a copy of its file to extrapolate)",
            )


def _base_name(name: str) -> str:
    for suffix in ("_los", "_nlos"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


# ---------------------------------------------------------------------------------------------
def _parse_condition(model: str, condition: str, table, where: str):
    if not isinstance(table, dict):
        raise ValidationError(where, table, "must be a table")
    if model in ("awgn", "field") and condition != "los":
        raise ValidationError(where, "[nlos]", f"the {model} model has a [los] table only")
    if model == "field":
        return _parse_field(table, where)
    if model == "tdl":
        return parse_tdl_condition(condition, table, where)
    if model == "awgn":
        spec = {"pathloss": s.Raw()}
    elif model == "exponential":
        spec = _exponential_spec(condition)
    else:
        clusters = table.get("clusters")
        dist = clusters.get("delay_distribution") if isinstance(clusters, dict) else None
        spec = _winner2_spec(condition, "uniform" if dist == "uniform" else "exponential")
    vals = s.parse(table, spec, where)
    pl = PathLoss.from_table(vals["pathloss"], f"{where}.pathloss")
    if model == "awgn":
        return AwgnCondition(condition, pl)
    if model == "exponential":
        return ExponentialCondition(
            condition,
            pl,
            vals["excess_delay_mean_s"],
            vals["mean_path_count"],
            vals.get("los_to_scatter_power_db", math.nan),
            vals.get("nlos_bias_mean_s", 0.0),
        )
    lsp, cl, sub = vals["lsp"], vals["clusters"], vals["subclusters"]
    names = ("ds", "sf", "k") if condition == "los" else ("ds", "sf")
    corr, chol = s.correlation_cholesky(lsp["cross_correlation"], names, where)
    offs, fracs = sub["delay_offsets_s"], sub["power_fractions"]
    if len(offs) != len(fracs):
        raise ValidationError(
            f"{where}.subclusters.power_fractions",
            list(fracs),
            f"one fraction per delay offset ({len(offs)} offsets)",
        )
    if abs(sum(fracs) - 1.0) > 1e-9:
        raise ValidationError(
            f"{where}.subclusters.power_fractions", list(fracs), "fractions must sum to 1"
        )
    if sub["num_split"] > cl["num_clusters"]:
        raise ValidationError(
            f"{where}.subclusters.num_split",
            sub["num_split"],
            f"an integer in [0, num_clusters = {cl['num_clusters']}]",
        )
    return Winner2Condition(
        condition=condition,
        pathloss=pl,
        ds_log10_mu=lsp["ds_log10_s_mu"],
        ds_log10_sigma=lsp["ds_log10_s_sigma"],
        k_db_mu=lsp.get("k_factor_db_mu", math.nan),
        k_db_sigma=lsp.get("k_factor_db_sigma", math.nan),
        correlation=corr,
        cholesky=chol,
        num_clusters=cl["num_clusters"],
        delay_distribution=cl["delay_distribution"],
        r_tau=cl.get("r_tau", math.nan),
        uniform_delay_max_s=cl.get("uniform_delay_max_s", math.nan),
        cluster_shadowing_std_db=cl["cluster_shadowing_std_db"],
        los_delay_scaling=tuple(cl.get("los_delay_scaling", ())),
        num_split=sub["num_split"],
        subcluster_offsets_s=offs,
        subcluster_fractions=fracs,
        nlos_bias_mean_s=vals.get("nlos_bias_mean_s", 0.0),
    )


def _parse_field(table: dict, where: str) -> FieldCondition:
    vals = s.parse(table, _FIELD_SPEC, where)
    g, sc, df = vals["ground"], vals["scatterers"], vals["diffuse"]
    lo, hi = sc["excess_delay_min_s"], sc["excess_delay_max_s"]
    if hi < lo:
        raise ValidationError(
            f"{where}.scatterers.excess_delay_max_s",
            hi,
            f"must be >= excess_delay_min_s = {lo:g}",
        )
    return FieldCondition(
        condition="los",
        ground_reflection=g["reflection"],
        polarization=g["polarization"],
        permittivity_a=g["permittivity_a"],
        permittivity_b=g["permittivity_b"],
        conductivity_c_s_m=g["conductivity_c_s_m"],
        conductivity_d=g["conductivity_d"],
        scatterer_count=sc["count"],
        scatterer_excess_delay_s=(lo, hi),
        scatterer_reflection_loss_db=sc["reflection_loss_db"],
        diffuse_ray_count=df["ray_count"],
        diffuse_delay_spread_s=df["delay_spread_s"],
        diffuse_power_ratio_db=df["power_ratio_db"],
    )


def parse_scenario(doc: dict, label: str) -> Scenario:
    """Validate a parsed scenario file (``label`` names it in errors)."""
    top = s.parse(doc, _TOP, f"{label}:")
    lo, hi = top["validity"]["carrier_frequency_hz"]
    if hi <= lo:
        raise ValidationError(
            f"{label}: validity.carrier_frequency_hz", [lo, hi], "[low, high] with low < high"
        )
    if top["model"] == "tr38901":  # the NLOS path loss refers to the LOS law: parse together
        plos, conds = parse_tr38901(top["los_probability"], top["los"], top["nlos"], label)
    else:
        plos = LosProbability.from_table(top["los_probability"], f"{label}: los_probability")
        conds = {}
        for c in CONDITIONS:
            if top[c] is not None:
                conds[c] = _parse_condition(top["model"], c, top[c], f"{label}: {c}")
    if not conds:
        raise ValidationError(f"{label}: los", s.MISSING, "a [los] and/or an [nlos] table")
    forced = None if len(conds) == 2 else next(iter(conds))
    return Scenario(
        name=top["name"],
        model=top["model"],
        los_probability=plos,
        los=conds.get("los"),
        nlos=conds.get("nlos"),
        forced=forced,
        carrier_frequency_range_hz=(lo, hi),
        source=top["source"],
        files=(label,),
    )


def _read_toml(path, label: str) -> dict:
    from phyloc.config import MAX_DEPTH, too_deep

    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise ValidationError(label, "<file>", f"not valid TOML: {e}") from None
    except RecursionError:  # arrays or inline tables nested thousands deep
        raise ValidationError(label, "<file>", "nests arrays or tables too deeply") from None
    deep = too_deep(doc)
    if deep is not None:
        raise ValidationError(
            label, deep, f"a channel file nests at most {MAX_DEPTH} levels of tables or arrays"
        )
    return doc


def load_file(path) -> Scenario:
    """Load and validate a scenario file (a user's own, or a shipped one by path)."""
    p = Path(path)
    if not p.is_file():
        raise ValidationError("scenario", str(path), "no such file")
    return parse_scenario(_read_toml(p, p.name), p.name)


# ---------------------------------------------------------------------------------------------
def shipped_root():
    """The shipped scenario files: package data ``phyloc.scenarios`` when installed, else (a
    source checkout imported from its working tree) the top-level ``channels/`` folder."""
    try:
        return importlib.resources.files("phyloc.scenarios")
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "channels"


@functools.cache
def _shipped_files() -> dict[str, object]:
    root = shipped_root()
    return {
        entry.name[: -len(".toml")]: entry
        for entry in root.iterdir()
        if entry.name.endswith(".toml")
    }


@functools.cache
def _registry() -> dict[str, tuple[str, ...]]:
    """Scenario name -> (stems of the files it joins)."""
    files = _shipped_files()
    names: dict[str, tuple[str, ...]] = {}
    for stem, entry in files.items():
        base = _base_name(stem)
        if base != stem:  # <base>_los / <base>_nlos
            names[stem] = (stem,)
            other = base + ("_nlos" if stem.endswith("_los") else "_los")
            if other in files:
                names[base] = (base + "_los", base + "_nlos")
        else:
            with entry.open("rb") as f:
                doc = tomllib.load(f)
            names[stem] = (stem,)
            for c in CONDITIONS:
                if c in doc:
                    names[f"{stem}_{c}"] = (stem,)
    return dict(sorted(names.items()))


def scenario_names() -> list[str]:
    """Names of the shipped scenarios (sorted)."""
    return list(_registry())


@functools.cache
def _load_shipped_file(stem: str) -> Scenario:
    entry = _shipped_files()[stem]
    with entry.open("rb") as f:
        try:
            doc = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise ValidationError(f"{stem}.toml", "<file>", f"not valid TOML: {e}") from None
    return parse_scenario(doc, f"{stem}.toml")


@functools.cache
def _load_name(name: str) -> Scenario:
    stems = _registry()[name]
    if len(stems) == 2:  # join <base>_los and <base>_nlos
        a, b = (_load_shipped_file(x) for x in stems)
        if not a.los_probability.same_as(b.los_probability):
            raise ValidationError(
                f"{stems[1]}.toml: los_probability",
                b.los_probability.coeffs,
                f"must equal the law in {stems[0]}.toml ({a.los_probability.coeffs})",
            )
        if a.model != b.model or a.carrier_frequency_range_hz != b.carrier_frequency_range_hz:
            raise ValidationError(f"{stems[1]}.toml: model", b.model, f"must match {stems[0]}.toml")
        return Scenario(
            name,
            a.model,
            a.los_probability,
            a.los,
            b.nlos,
            None,
            a.carrier_frequency_range_hz,
            a.source + " | " + b.source,
            a.files + b.files,
        )
    scn = _load_shipped_file(stems[0])
    suffix = name[len(_base_name(name)) :]
    if suffix and name != stems[0]:  # <base>_los from a two-condition <base>.toml
        return scn.with_condition(suffix[1:])
    return Scenario(
        name,
        scn.model,
        scn.los_probability,
        scn.los,
        scn.nlos,
        scn.forced,
        scn.carrier_frequency_range_hz,
        scn.source,
        scn.files,
    )


def load_scenario(scenario) -> Scenario:
    """A :class:`Scenario` from a shipped name, a file path or a :class:`Scenario`.

    Parameters
    ----------
    scenario : str, os.PathLike or Scenario
        ``"winner2_c2"`` (condition drawn per link), ``"winner2_c2_los"`` /
        ``"winner2_c2_nlos"`` (forced), ``"awgn"``, ``"exponential"``, ... (see
        :func:`scenario_names`), or the path of a scenario TOML file.

    Raises
    ------
    ValidationError
        Unknown name (the message lists the valid ones), or a missing / out-of-range key in
        the file (the message names the key, the value and the allowed range).

    Examples
    --------
    >>> scn = load_scenario("winner2_c2")
    >>> scn.model, scn.forced, scn.los.num_clusters, scn.nlos.num_clusters
    ('winner2', None, 8, 20)
    """
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, os.PathLike):
        return load_file(scenario)
    if not isinstance(scenario, str):
        raise ValidationError("scenario", scenario, "a scenario name, a file path or a Scenario")
    if scenario in _registry():
        return _load_name(scenario)
    if scenario.endswith(".toml") or os.sep in scenario or Path(scenario).is_file():
        return load_file(scenario)
    raise ValidationError(
        "scenario",
        scenario,
        "unknown scenario; valid names: "
        + ", ".join(scenario_names())
        + " (or the path of a scenario TOML file)",
    )
