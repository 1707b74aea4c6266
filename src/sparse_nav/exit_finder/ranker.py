"""The learned door ranker: gradient-boosted trees over :data:`~.doors.FEATURE_NAMES`
(ROS-free).

The model gives each door candidate the probability that it is a true exit (within half a door
width plus 0.3 m of one). It is trained by ``bench/train_door_ranker.py`` on simulator rooms that
the benchmark does not score, and shipped as ``door_ranker.json`` next to this module: plain
JSON (the trees' split features, thresholds, children and leaf values), read with ``json``, never
unpickled, and checked against the feature list of this code before use. Evaluating it needs
numpy only; scikit-learn is needed to train it.
"""
import functools
import json
import math
import os

import numpy as np

from sparse_nav.exit_finder.doors import FEATURE_NAMES

MODEL_FORMAT = "sparse_nav door ranker"
MODEL_VERSION = 1
PACKAGED_MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "door_ranker.json")


class RankerModelError(ValueError):
    """A ranker model file that cannot be used; the message says why."""


class DoorRanker:
    """Binary gradient boosting: probability = sigmoid(init + learning_rate * sum of the trees'
    leaf values). A tree goes left where ``x[feature] <= threshold``."""

    def __init__(self, init, learning_rate, trees, info=None):
        self.init = float(init)
        self.learning_rate = float(learning_rate)
        self.info = dict(info or {})
        # All trees in one set of node arrays; children are global node indices, -1 at leaves.
        feature, threshold, left, right, value, roots = [], [], [], [], [], []
        offset = 0
        for tree in trees:
            roots.append(offset)
            n = len(tree["feature"])
            for key in ("threshold", "left", "right", "value"):
                if len(tree[key]) != n:
                    raise RankerModelError(f"a tree's '{key}' has {len(tree[key])} entries "
                                           f"for {n} nodes")
            kids_l, kids_r = np.asarray(tree["left"], int), np.asarray(tree["right"], int)
            node = np.arange(n)
            inner = kids_l >= 0
            # Children come after their parent (as scikit-learn writes them): no cycles.
            if np.any(kids_l >= n) or np.any(kids_r >= n) or np.any(inner != (kids_r >= 0)) \
                    or np.any(inner & ((kids_l <= node) | (kids_r <= node))):
                raise RankerModelError("a tree's child indices do not form a tree")
            feature.append(np.asarray(tree["feature"], int))
            threshold.append(np.asarray(tree["threshold"], float))
            left.append(np.where(kids_l < 0, -1, kids_l + offset))
            right.append(np.where(kids_r < 0, -1, kids_r + offset))
            value.append(np.asarray(tree["value"], float))
            offset += n
        if not roots:
            raise RankerModelError("the model has no trees")
        self.feature = np.concatenate(feature)
        self.threshold = np.concatenate(threshold)
        self.left = np.concatenate(left)
        self.right = np.concatenate(right)
        self.value = np.concatenate(value)
        self.roots = np.array(roots)
        inner = self.left >= 0
        if np.any(inner & ((self.feature < 0) | (self.feature >= len(FEATURE_NAMES)))):
            raise RankerModelError("a tree splits on a feature index outside the feature list")
        if not (np.all(np.isfinite(self.value)) and np.all(np.isfinite(self.threshold[inner]))
                and math.isfinite(self.init) and math.isfinite(self.learning_rate)):
            raise RankerModelError("the model holds non-finite numbers")

    @classmethod
    def from_dict(cls, data):
        """A ranker from the JSON form; RankerModelError when it is not one for this code."""
        if not isinstance(data, dict) or data.get("format") != MODEL_FORMAT:
            raise RankerModelError(f"not a {MODEL_FORMAT} model")
        if data.get("version") != MODEL_VERSION:
            raise RankerModelError(f"model version {data.get('version')!r}, this code reads "
                                   f"{MODEL_VERSION}")
        if list(data.get("feature_names", [])) != list(FEATURE_NAMES):
            raise RankerModelError("the model was trained on other features than this code "
                                   "computes; train it again (bench/train_door_ranker.py)")
        try:
            return cls(data["init"], data["learning_rate"], data["trees"], data.get("info"))
        except RankerModelError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise RankerModelError(f"malformed model: {exc!r}") from None

    def to_dict(self):
        """The JSON form (:meth:`from_dict` reads it back)."""
        trees = []
        ends = list(self.roots[1:]) + [len(self.feature)]
        for start, end in zip(self.roots, ends):
            left, right = self.left[start:end], self.right[start:end]
            trees.append({"feature": self.feature[start:end].tolist(),
                          "threshold": self.threshold[start:end].tolist(),
                          "left": np.where(left < 0, -1, left - start).tolist(),
                          "right": np.where(right < 0, -1, right - start).tolist(),
                          "value": self.value[start:end].tolist()})
        return {"format": MODEL_FORMAT, "version": MODEL_VERSION,
                "feature_names": list(FEATURE_NAMES), "info": self.info, "init": self.init,
                "learning_rate": self.learning_rate, "trees": trees}

    def probability(self, x):
        """(N,) probability that each row of the feature matrix x (N, len(FEATURE_NAMES)) is a
        true exit."""
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != len(FEATURE_NAMES):
            raise ValueError(f"features must be (N, {len(FEATURE_NAMES)}), got {x.shape}")
        if not len(x):
            return np.zeros(0)
        rows = np.arange(len(x))[:, None]
        node = np.broadcast_to(self.roots, (len(x), len(self.roots))).copy()
        while True:
            inner = self.left[node] >= 0
            if not inner.any():
                break
            go_left = x[rows, self.feature[node]] <= self.threshold[node]
            nxt = np.where(go_left, self.left[node], self.right[node])
            node = np.where(inner, nxt, node)
        raw = self.init + self.learning_rate * self.value[node].sum(axis=1)
        return 1.0 / (1.0 + np.exp(-raw))


@functools.lru_cache(maxsize=4)
def load_ranker(path=""):
    """The ranker in ``path`` (JSON), or the packaged one for ``""``; RankerModelError with the
    reason when the file is missing, unreadable, not JSON or not a model for this code."""
    path = path or PACKAGED_MODEL
    try:
        with open(path, "r", encoding="utf-8") as handle:
            data = json.load(handle)
    except OSError as exc:
        raise RankerModelError(f"cannot read the ranker model {path}: {exc.strerror}") from None
    except ValueError as exc:
        raise RankerModelError(f"the ranker model {path} is not JSON: {exc}") from None
    try:
        return DoorRanker.from_dict(data)
    except RankerModelError as exc:
        raise RankerModelError(f"{path}: {exc}") from None
