"""A Wi-Fi radio map from survey walks, and the positions it gives a walk's scans (issue 60 §2–§3).

Build (:func:`wearnav.fuse.radiobuild.build`): every Wi-Fi scan of the survey walks (:class:`~wearnav.recording.WifiScans`)
is placed where the walker was at its time (:mod:`wearnav.fuse.survey`: the walk's PDR path warped
onto its surveyed points) and becomes a fingerprint, one RSSI per access point of the map
(:func:`wearnav.fuse.radioscans.fingerprints`). A scan is the readings sharing one time; of an access point heard twice in
a scan the fresher reading counts; readings older than ``stale_s`` (cached by the phone,
``t − t_seen``) are left out; an access point the scan did not hear reads ``missing_dbm``. The map
keeps the access points heard in at least ``min_scans_per_ap`` of its scans.

Model: scikit-learn, no hand-written learner. The floor is a distance-weighted k-nearest-neighbour
vote over every scan of the map (:class:`~sklearn.neighbors.KNeighborsClassifier`); x, y a
distance-weighted k-nearest-neighbour mean over the scans of that floor
(:class:`~sklearn.neighbors.KNeighborsRegressor`; ``model="extra-trees"``:
:class:`~sklearn.ensemble.ExtraTreesRegressor`, kept for the comparison of
:mod:`wearnav.bench.radiomap`). Its 1-σ per axis: the neighbours' weighted spread about the
estimate (the trees' spread for extra trees), at least ``min_sigma_m``, mapped to a calibrated σ
by a ``cv_folds``-fold cross-validation over the map's own walks (each walk held out whole): the
held-out scans are cut into :data:`SIGMA_BINS` equal groups by their raw σ, and each group's σ is the
one that puts 68 % of its errors inside the 68 % radius (:data:`wearnav.fuse.RADIUS_68` σ), as a
fix's reported accuracy is; between the groups' middles σ is interpolated (never falling as the raw
σ grows). One scale for all (``sigma_scale``, kept on the card) overstated the σ of the widest
neighbourhoods: on IPIN 2023 the top fifth's errors had a 68 % radius of 15.7 m, the one scale gave
them 25–95 m, so the phone's fixes outweighed the radio map where they were worst (underground);
without the phone's fixes the one scale is kept. The same cross-validation gives the card's numbers.

Storage (:meth:`RadioMap.save`): a folder holding ``radiomap.npz`` (the fingerprints, their
positions, floors and walks: the learner is fitted again on load, so no pickle is read),
``card.json`` (the config, the walks, the access points, the validation) and ``README.md`` (the card
for a person). Use (:meth:`RadioMap.locate`): a recording's scans → positions with σ and floor
(:class:`RadioPositions`); a scan sharing fewer than ``min_common_aps`` access points with the map
gets none; a recording of which no scan shares one is another site (:meth:`RadioMap.fits`).

A walk's scans get their floors as one sequence (:func:`wearnav.fuse.radiofloor.floor_sequence`, a hidden floor that changes
as rarely as it did between the survey walks' consecutive scans, each vote as right as the map's
cross-validation found), and each position comes from its floor's scans: a stray vote no longer
puts a scan in another floor's frame (ILC2's floors each have their own).

The floor (:func:`wearnav.fuse.radiofloor.floor_over_time`): where the survey walks carry a barometer and surveyed floors, the
map keeps the site's floor levels (:func:`wearnav.fuse.floors.fit_floor_levels`, on its card); a
walk with a barometer then follows the barometer's floor track from the start floor that agrees with
most of its scans' floor votes (Wi-Fi says which floor, the barometer when it changes), else the votes
alone, smoothed. As location fixes: :mod:`wearnav.fuse.radiofixes`. Decisions: docs/decisions/0048-radio-map.md,
0049-radio-map-bench-floor-weights.md, 0050-radio-sigma-without-gnss.md.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wearnav.core.fileio import atomic_path, write_text_atomic
from wearnav.core.textio import read_json
from wearnav.errors import ConfigError, FormatError, ValidationError
from wearnav.fuse.config import RADIUS_68, SURVEY_ODOMETRY
from wearnav.fuse.floors import FloorLevels
from wearnav.fuse.radiofloor import floor_sequence
from wearnav.fuse.radioscans import Scans, fingerprints, scans_of
from wearnav.recording import Recording, WifiScans

FORMAT = "wearnav.radiomap"
FORMAT_VERSION = 1
MAP_NPZ, CARD_JSON, CARD_MD = "radiomap.npz", "card.json", "README.md"
MODELS = ("knn", "extra-trees")
NO_FIT = "the radio map does not fit this recording: no access point in common"
SIGMA_BINS = 5  # the radio map's σ calibration: groups of held-out scans by their raw σ


@dataclasses.dataclass(frozen=True)
class RadioMapConfig:
    """Every constant of a radio map (stored on its card). Compared on held-out walks (prototype runs,
    the same folds as :mod:`wearnav.bench.radiomap`, so these choices saw the data they are scored on):
    ILC2 site 1 floor F2, walks held out in 10 folds, k = 8: readings older than 4 s or 8 s left out
    4.44 / 4.43 m median against 5.08 m (2 s) and 5.92 m (none left out), ``stale_s`` 6 s between them;
    IPIN 2023 trials held out: k = 3, 5, 8, 12 gave 7.47, 7.40, 7.40, 7.51 m (Euclidean; Manhattan,
    Bray-Curtis and exponential or "powed" RSSI no better)."""

    model: str = "knn"  # MODELS
    k: int = 8  # neighbours (floor vote and position)
    missing_dbm: float = -100.0  # an access point the scan did not hear (weaker readings are clipped to it)
    stale_s: float = 6.0  # readings older than this at the scan's time are left out (t - t_seen)
    min_scans_per_ap: int = 3  # access points heard in fewer of the map's scans are not kept
    min_common_aps: int = 3  # a scan sharing fewer access points with the map gets no position
    min_sigma_m: float = 1.0  # the raw σ's floor (neighbours that agree exactly)
    cv_folds: int = 5  # walks held out whole to calibrate σ and validate
    trees: int = 100  # extra-trees only
    # x, y from the scans of the floor voted for (True), or from every scan (False: the floors share
    # one frame, e.g. lat/lon: on IPIN 2023, trials held out, 7.4 m median against 8.1 m per floor,
    # where a wrong floor vote costs the position too); None: build decides (:func:`shared_frame`)
    per_floor: bool | None = None
    odometry: str = SURVEY_ODOMETRY  # where survey walks run between surveyed points

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ConfigError(f"radio map model {self.model!r}: not one of {', '.join(MODELS)}")
        if self.k < 1 or self.min_scans_per_ap < 1 or self.min_common_aps < 1 or self.cv_folds < 2:
            raise ConfigError("radio map config: k, min_scans_per_ap, min_common_aps >= 1 and cv_folds >= 2")
        if not -130.0 <= self.missing_dbm <= -50.0 or not self.stale_s > 0 or not self.min_sigma_m > 0:
            raise ConfigError("radio map config: missing_dbm in -130..-50 dBm, stale_s and min_sigma_m > 0")


# ---- the model ----------------------------------------------------------------------------------


@dataclasses.dataclass
class RadioPositions:
    """Positions a radio map gives a recording's scans: ``t`` (P,) s, ``xy`` (P, 2) m in the map's
    frame, ``sigma_m`` (P,) 1-σ per axis, ``floor`` (P,), ``common_aps`` (P,) access points shared
    with the map; ``info`` how many scans there were and why some gave none."""

    t: np.ndarray
    xy: np.ndarray
    sigma_m: np.ndarray
    floor: np.ndarray
    common_aps: np.ndarray
    info: dict[str, Any]

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def accuracy_m(self) -> np.ndarray:
        """The 68 % radius, as a phone reports a fix's accuracy (RADIUS_68 σ)."""
        return RADIUS_68 * self.sigma_m


class _Learner:
    """The fitted scikit-learn models of a map: a floor vote over every scan, a position model per floor."""

    def __init__(self, x: np.ndarray, xy: np.ndarray, floor: np.ndarray, cfg: RadioMapConfig):
        from sklearn.ensemble import ExtraTreesRegressor
        from sklearn.neighbors import KNeighborsClassifier, KNeighborsRegressor

        self.cfg = cfg
        self.floors = np.unique(floor)
        self.vote = None
        if self.floors.size > 1:
            self.vote = KNeighborsClassifier(min(cfg.k, len(x)), weights="distance").fit(x, floor.astype(np.int64))
        self.by_floor: dict[float | None, tuple[Any, np.ndarray]] = {}
        for f in self.floors if cfg.per_floor is not False else [None]:
            on = floor == f if f is not None else np.ones(len(x), bool)
            if cfg.model == "knn":
                model: Any = KNeighborsRegressor(min(cfg.k, int(on.sum())), weights="distance").fit(x[on], xy[on])
            else:
                model = ExtraTreesRegressor(cfg.trees, min_samples_leaf=2, random_state=0, n_jobs=1).fit(x[on], xy[on])
            self.by_floor[None if f is None else float(f)] = (model, xy[on])

    def predict(self, x: np.ndarray, floor: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N, 2) positions, (N,) raw σ (per axis, before the map's scale), (N,) floors: the vote's,
        or ``floor`` where given (the position then from that floor's scans)."""
        if floor is None:
            floor = (
                np.full(len(x), float(self.floors[0])) if self.vote is None else self.vote.predict(x).astype(np.float64)
            )
        xy, sigma = np.zeros((len(x), 2)), np.zeros(len(x))
        for f, (model, train_xy) in self.by_floor.items():
            on = floor == f if f is not None else np.ones(len(x), bool)
            if not on.any():
                continue
            if self.cfg.model == "knn":
                dist, idx = model.kneighbors(x[on])
                w = 1.0 / np.maximum(dist, 1e-9)
                w /= w.sum(axis=1, keepdims=True)
                est = np.einsum("nk,nkd->nd", w, train_xy[idx])
                spread = np.einsum("nk,nk->n", w, np.sum((train_xy[idx] - est[:, None]) ** 2, axis=2))
            else:
                per_tree = np.stack([tree.predict(x[on]) for tree in model.estimators_])  # (T, N, 2)
                est = per_tree.mean(axis=0)
                spread = np.mean(np.sum((per_tree - est) ** 2, axis=2), axis=0)
            xy[on], sigma[on] = est, np.sqrt(spread / 2.0)  # per axis: half the 2-D mean square
        return xy, np.maximum(sigma, self.cfg.min_sigma_m), floor


def cross_validate(
    scans: Scans, bssids: Sequence[str], cfg: RadioMapConfig, folds: int, groups: dict[str, str] | None = None
) -> dict[str, np.ndarray]:
    """Each walk's scans predicted by the model fitted on the other walks (``folds`` groups of walks,
    scikit-learn's GroupKFold; ``groups``: walk → the group held out with it, e.g. IPIN's repetitions
    of one route): errors (m), raw σ, floor right, for every scan sharing ``min_common_aps`` access
    points with the rest (S,) arrays; fewer than 2 groups: empty."""
    from sklearn.model_selection import GroupKFold

    assert scans.xy is not None and scans.floor is not None and scans.walk is not None
    x, _ = fingerprints(scans, bssids, cfg.missing_dbm)
    walks = np.array([(groups or {}).get(str(w), str(w)) for w in scans.walk], dtype=object)
    n_walks = np.unique(walks).size
    out: dict[str, list[np.ndarray]] = {"error_m": [], "sigma_raw_m": [], "floor_right": []}
    if n_walks < 2:
        return {k: np.empty(0) for k in out}
    for train, test in GroupKFold(min(folds, n_walks)).split(x, groups=walks):
        heard = (x[train] > cfg.missing_dbm).sum(axis=0) > 0  # what a map of these walks would know
        common = (x[test][:, heard] > cfg.missing_dbm).sum(axis=1)
        test = test[common >= cfg.min_common_aps]
        if test.size == 0:
            continue
        learner = _Learner(x[train][:, heard], scans.xy[train], scans.floor[train], cfg)
        xy, sigma, floor = learner.predict(x[test][:, heard])
        out["error_m"].append(np.linalg.norm(xy - scans.xy[test], axis=1))
        out["sigma_raw_m"].append(sigma)
        out["floor_right"].append(floor == scans.floor[test])
    return {k: np.concatenate(v) if v else np.empty(0) for k, v in out.items()}


def error_summary(err: np.ndarray, floor_right: np.ndarray | None = None) -> dict[str, Any]:
    """Median / p75 / p95 of errors (m), their count, and the share of floors right."""
    if err.size == 0:
        return {"n": 0}
    q = np.percentile(err, [50, 75, 95])
    out: dict[str, Any] = {"n": int(err.size), "median_m": round(float(q[0]), 2), "p75_m": round(float(q[1]), 2)}
    out["p95_m"] = round(float(q[2]), 2)
    if floor_right is not None and floor_right.size:
        out["floor_right"] = round(float(np.mean(floor_right)), 4)
    return out


class RadioMap:
    """A radio map: its survey fingerprints (``scans`` with positions), the access points it knows
    (``bssids``), its config, its σ scale and its card (module docstring)."""

    def __init__(
        self, scans: Scans, bssids: Sequence[str], cfg: RadioMapConfig, sigma_scale: float, card: dict[str, Any]
    ):
        assert scans.xy is not None and scans.floor is not None
        self.scans, self.bssids, self.cfg = scans, list(bssids), cfg
        self.sigma_scale, self.card = float(sigma_scale), card
        self._bssid_set = set(self.bssids)
        x, _ = fingerprints(scans, self.bssids, cfg.missing_dbm)
        self._learner = _Learner(x, scans.xy, scans.floor, cfg)

    @property
    def origin(self) -> tuple[float, float] | None:
        """The lat/lon (degrees) its positions' east/north are about (:func:`wearnav.core.geo.latlon_to_local`'s
        frame), where its survey walks shared one; None: a frame with no place on Earth (a site plan's),
        or a map built before the card kept it."""
        o = self.card.get("origin")
        return None if o is None else (float(o[0]), float(o[1]))

    @property
    def floor_levels(self) -> FloorLevels | None:
        """The site's floor levels measured on the map's walks (None: they had no barometer or one floor)."""
        d = self.card.get("floor_levels")
        return None if d is None else FloorLevels.from_dict(d)

    # ---- use --------------------------------------------------------------------------------

    def common_aps(self, wifi: WifiScans | None) -> int:
        """How many of the map's access points the recording heard at all."""
        return 0 if wifi is None else len(self._bssid_set.intersection(pd.unique(wifi.bssid)))

    def fits(self, rec: Recording) -> bool:
        """Whether any access point of the map is in the recording's scans (a map of another site: no)."""
        return self.common_aps(rec.wifi) > 0

    def predict(
        self, x: np.ndarray, floor: np.ndarray | None = None, by_group: bool = True
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fingerprints (N, A) over :attr:`bssids` (:func:`wearnav.fuse.radioscans.fingerprints`) → positions (N, 2), σ (N,) m
        per axis (calibrated by groups; ``by_group`` False: by the one scale), floors (N,): each
        scan's own floor vote, or ``floor`` where given."""
        xy, sigma_raw, floor = self._learner.predict(x, floor)
        cal = self.card.get("sigma_calibration")
        if not cal or not by_group:  # one scale (a map of too few scans to calibrate by groups, or asked)
            return xy, sigma_raw * self.sigma_scale, floor
        return xy, np.interp(sigma_raw, cal["sigma_raw_m"], cal["sigma_m"]), floor

    def locate(self, wifi: WifiScans | None, by_group: bool = True) -> RadioPositions:
        """Every scan sharing ``min_common_aps`` access points with the map → position, σ (``by_group``:
        :meth:`predict`), floor."""
        empty = np.empty(0)
        if wifi is None:
            return RadioPositions(empty, np.empty((0, 2)), empty, empty, empty, {"scans": 0, "positions": 0})
        scans = scans_of(wifi, self.cfg.stale_s)
        x, common = fingerprints(scans, self.bssids, self.cfg.missing_dbm)
        use = common >= self.cfg.min_common_aps
        xy, sigma, floor = self.predict(x[use], by_group=by_group) if use.any() else (np.empty((0, 2)), empty, empty)
        switch = self.card.get("floor_switch_per_scan")
        floor_right = self.card.get("validation", {}).get("floor_right")
        if floor.size > 1 and switch is not None and floor_right is not None and len(self._learner.floors) > 1:
            votes = floor
            floor = floor_sequence(votes, self._learner.floors.astype(np.float64), float(floor_right), float(switch))
            if (floor != votes).any():  # a scan's position from the floor of the sequence
                xy, sigma, floor = self.predict(x[use], floor, by_group=by_group)
        info = {
            "scans": len(scans),
            "positions": int(use.sum()),
            "scans_too_few_common_aps": int((~use).sum()),
            "access_points_in_common": self.common_aps(wifi),
        }
        return RadioPositions(scans.t[use], xy, sigma, floor, common[use], info)

    # ---- storage ----------------------------------------------------------------------------

    def save(self, folder: str | Path) -> Path:
        """Write the map folder (module docstring); the folder may exist only as an earlier map."""
        folder = Path(folder)
        if folder.exists() and (not folder.is_dir() or (any(folder.iterdir()) and not (folder / CARD_JSON).is_file())):
            raise ConfigError("exists and is not a radio map folder: choose a new --out", folder)
        folder.mkdir(parents=True, exist_ok=True)
        s = self.scans
        assert s.xy is not None and s.floor is not None and s.walk is not None
        walks, walk_index = np.unique(s.walk.astype(str), return_inverse=True)
        ap_index = pd.Index(self.bssids).get_indexer(s.bssid)
        keep = ap_index >= 0
        with atomic_path(folder / MAP_NPZ) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(
                f,
                t=s.t,
                xy=s.xy,
                floor=s.floor,
                walk_index=walk_index.astype(np.int32),
                walks=walks.astype(str),
                bssids=np.array(self.bssids, dtype=str),
                reading_scan=s.scan[keep].astype(np.int32),
                reading_ap=ap_index[keep].astype(np.int32),
                reading_rssi_dbm=s.rssi_dbm[keep].astype(np.float32),
            )
        write_text_atomic(json.dumps(self.card, indent=2), folder / CARD_JSON)
        write_text_atomic(card_markdown(self.card), folder / CARD_MD)
        return folder

    @classmethod
    def load(cls, folder: str | Path) -> RadioMap:
        """A map folder written by :meth:`save` (a clear error for anything else)."""
        folder = Path(folder)
        if not (folder / CARD_JSON).is_file() or not (folder / MAP_NPZ).is_file():
            raise FormatError(
                f"not a radio map folder (no {CARD_JSON} and {MAP_NPZ}; `wearnav radiomap build` writes one)", folder
            )
        card = read_json(folder / CARD_JSON)
        if not isinstance(card, dict) or card.get("format") != FORMAT or card.get("version") != FORMAT_VERSION:
            raise FormatError(f"{CARD_JSON} is not a {FORMAT} card of version {FORMAT_VERSION}", folder)
        try:
            cfg = RadioMapConfig(**card["config"])
            with np.load(folder / MAP_NPZ, allow_pickle=False) as z:
                bssids = [str(b) for b in z["bssids"]]
                walks = z["walks"].astype(str).astype(object)
                scans = Scans(
                    z["t"],
                    z["reading_scan"].astype(np.int64),
                    np.array(bssids, dtype=object)[z["reading_ap"]],
                    z["reading_rssi_dbm"].astype(np.float64),
                    z["xy"],
                    z["floor"],
                    walks[z["walk_index"]],
                )
        except (KeyError, TypeError, ValueError, OSError, IndexError) as exc:
            raise FormatError(f"corrupt radio map ({exc.__class__.__name__}: {exc})", folder) from None
        return cls(scans, bssids, cfg, float(card["sigma_scale"]), card)


def sigma_calibration(sigma_raw: np.ndarray, error: np.ndarray) -> dict[str, list[float]] | None:
    """Raw σ → calibrated σ per axis (module docstring): per group of held-out scans by raw σ, the
    group's median raw σ and the σ whose 68 % radius holds 68 % of its errors, non-decreasing; None
    with fewer than 10 scans a group."""
    if error.size < 10 * SIGMA_BINS:
        return None
    order = np.argsort(sigma_raw, kind="stable")
    groups = np.array_split(order, SIGMA_BINS)
    x = np.array([float(np.median(sigma_raw[g])) for g in groups])
    y = np.maximum.accumulate([float(np.percentile(error[g], 68)) / RADIUS_68 for g in groups])
    x = np.maximum.accumulate(x + 1e-9 * np.arange(x.size))  # strictly increasing for np.interp
    return {"sigma_raw_m": [round(float(v), 4) for v in x], "sigma_m": [round(float(v), 4) for v in y]}


def map_access_points(scans: Scans, min_scans: int) -> list[str]:
    """The access points heard in at least ``min_scans`` scans, sorted."""
    counts = pd.Series(scans.bssid).value_counts()
    return sorted(str(b) for b in counts.index[counts.to_numpy() >= min_scans])


def from_scans(
    scans: Scans,
    cfg: RadioMapConfig,
    walks_info: list[dict] | None = None,
    source: str = "",
    groups: dict[str, str] | None = None,
    group_by: str = "walk",
) -> RadioMap:
    """The map of placed survey scans: its access points, the σ scale and validation of a
    cross-validation over its walks (module docstring; ``groups``: walk → what is held out with it,
    named ``group_by``), and its card."""
    if len(scans) == 0:
        raise ValidationError("no placed Wi-Fi scans to build a radio map from (walks with Wi-Fi and surveyed points?)")
    bssids = map_access_points(scans, cfg.min_scans_per_ap)
    if not bssids:
        raise ValidationError(f"no access point is heard in {cfg.min_scans_per_ap} scans of the survey walks")
    cv = cross_validate(scans, bssids, cfg, cfg.cv_folds, groups)
    ratio = cv["error_m"] / cv["sigma_raw_m"] if cv["error_m"].size else np.empty(0)
    scale = float(np.percentile(ratio, 68) / RADIUS_68) if ratio.size >= 10 else 1.0
    calibration = sigma_calibration(cv["sigma_raw_m"], cv["error_m"])
    if calibration:
        sigma = np.interp(cv["sigma_raw_m"], calibration["sigma_raw_m"], calibration["sigma_m"])
    else:
        sigma = scale * cv["sigma_raw_m"]
    inside = float(np.mean(cv["error_m"] <= RADIUS_68 * sigma)) if ratio.size else None
    assert scans.walk is not None and scans.floor is not None
    walks = sorted(set(scans.walk.astype(str)))
    n_groups = len({(groups or {}).get(w, w) for w in walks})
    card = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "source": source,
        "config": dataclasses.asdict(cfg),
        "sigma_scale": scale,  # exact: the map read back gives the same σ
        "sigma_calibration": calibration,  # raw σ → σ (m), by groups (module docstring); None: the scale
        "walks": walks,
        "positions": "per floor (the floors' frames differ)"
        if cfg.per_floor is not False
        else "one frame for every floor",
        "walks_info": walks_info or [],
        "scans": len(scans),
        "floors": {
            str(int(f) if float(f).is_integer() else f): int(n)
            for f, n in zip(*np.unique(scans.floor, return_counts=True))
        },
        "access_points": bssids,
        "validation": {
            "how": f"{min(cfg.cv_folds, n_groups)}-fold cross-validation over the map's walks (each {group_by} held out whole)",
            **error_summary(cv["error_m"], cv["floor_right"]),
            "share_inside_68_radius": None if inside is None else round(inside, 4),
        },
    }
    return RadioMap(scans, bssids, cfg, scale, card)


def shared_frame(recs: Sequence[Recording]) -> bool:
    """Whether every walk's positions are in one frame across floors: one lat/lon origin for all
    (IPIN's venue); else (ILC2: each floor's plan its own frame) positions are per floor."""
    return common_origin(recs) is not None


def common_origin(recs: Sequence[Recording]) -> tuple[float, float] | None:
    """The lat/lon origin (degrees) every walk's positions are about, where they share one: the map's
    place on Earth (:attr:`RadioMap.origin`); None where they have none (a site plan's frame) or several."""
    origins = {(r.meta.get("origin_lat"), r.meta.get("origin_lon")) for r in recs}
    if len(origins) != 1:
        return None
    lat, lon = next(iter(origins))
    return None if lat is None or lon is None else (float(lat), float(lon))


def walk_group(rec: Recording, group_by: str) -> str:
    """What is held out with a walk in the cross-validation: ``meta[group_by]`` (e.g. IPIN's
    ``trial``: its repetitions walk one route), the walk itself for ``walk`` or where meta lacks it."""
    value = rec.meta.get(group_by) if group_by != "walk" else None
    return rec.name if value is None else f"{group_by} {value}"


def card_markdown(card: dict[str, Any]) -> str:
    """The card for a person: what the map was built from and how well it placed held-out walks."""
    v = card["validation"]
    lines = [
        "# Radio map",
        "",
        f"Built by `wearnav radiomap build` from {len(card['walks'])} survey walks"
        + (f" of `{card['source']}`" if card.get("source") else "")
        + f": {card['scans']} Wi-Fi scans placed on the walks' PDR paths between their surveyed points, "
        f"{len(card['access_points'])} access points, floors {', '.join(card['floors'])}.",
        "",
        f"Model: {card['config']['model']} (k = {card['config']['k']}), scikit-learn; σ scale {card['sigma_scale']}.",
        "",
        "Positions: east/north (m) about "
        + (
            f"lat {card['origin'][0]:.7f}, lon {card['origin'][1]:.7f} (WGS-84 east-north-up): a recording about "
            "another origin gets them converted"
            if card.get("origin")
            else "the survey walks' own frame (no lat/lon origin): they join only recordings without one"
        )
        + ".",
        "",
        f"Validation ({v['how']}): median {v.get('median_m')} m, p75 {v.get('p75_m')} m, p95 {v.get('p95_m')} m "
        f"over {v.get('n', 0)} scans; floor right {v.get('floor_right')}; share of errors inside the 68 % radius "
        f"{v.get('share_inside_68_radius')}.",
        "",
        "The access points, the walks and the config are in card.json.",
        "",
    ]
    return "\n".join(lines)
