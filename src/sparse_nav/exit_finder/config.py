"""Parameters of every exit finder method, with their defaults written once (ROS-free).

Units: a monocular ORB-SLAM cloud has no metric scale, so every distance below is in **cloud
radii** ("r.u."): the planar points are centred on their mean and divided by the cloud radius,
the ``scale_percentile``-th percentile of the points' distances from that mean. A room seen from
inside has its walls at roughly 0.6-1.0 r.u. from the centre whatever the SLAM units are, which is
also about where seed 000's ORB-SLAM units put them; so "round to two decimals" becomes "round to
0.01 r.u." and every threshold means the same thing on any cloud. Angles are in degrees.
"""
import dataclasses
import math

LINE_SCORES = ("rpcl", "count", "extent")
VIEWPOINTS = ("origin", "estimate", "centroid")


@dataclasses.dataclass
class ExitFinderConfig:
    """Every threshold of the exit finder; call :meth:`validate` after changing one."""

    # -- input and normalisation --------------------------------------------------------------
    min_points: int = 20               # fewer finite points (before or after IPCL): refused
    collinear_ratio: float = 0.02      # minor / major principal spread below this: collinear
    scale_percentile: float = 80.0     # cloud radius = this percentile of distances from the mean
    round_decimals: int = 2            # seed step 2: round normalised coordinates, de-duplicate
    drop_non_finite: bool = True       # drop NaN/inf rows (counted); False refuses them

    # -- IPCL (seed step 3): a point survives a round iff it has >= min_neighbours others within
    #    radius; all removals of a round are applied at its end.
    ipcl_radius: float = 0.05          # r.u.
    ipcl_min_neighbours: int = 3
    ipcl_rounds: int = 2

    # -- RANSAC lines (seed step 4)
    ransac_lines: int = 6              # lines found one after another on the remaining points
    ransac_iterations: int = 300       # sampled point pairs per line
    ransac_max_eval_points: int = 4000  # hypotheses are counted on at most this many points
    line_near_dist: float = 0.05       # r.u.: a point is "near" a line (inlier, removal, score)
    ransac_refit: bool = True          # refit the best hypothesis to its inliers (least squares)
    seed: int = 0                      # numpy Generator seed of every random draw

    # -- line scores (seed step 5)
    line_score: str = "rpcl"           # "rpcl" (seed), "count", or "extent" (furthest two points)
    rpcl_radius: float = 0.02          # r.u.; RPCL keeps the near points that PCL would remove:
    rpcl_min_neighbours: int = 8       # fewer than this many other near points within rpcl_radius
    distinct_lines: bool = True        # skip a line that repeats a better one (thick walls)
    distinct_angle_deg: float = 15.0   # ... closer in angle than this
    distinct_offset: float = 0.2       # ... and whose mid point is this close to the other (r.u.)

    # -- quadrilateral (seed step 6)
    min_corner_angle_deg: float = 20.0  # neighbouring room sides must differ by this much
    max_corner_dist: float = 3.0       # r.u.: a corner further from the centre: degenerate
    min_room_area: float = 0.2         # quadrilateral area below this (r.u.^2): degenerate

    # -- perimeter samples (seed steps 7, 8)
    perimeter_samples: int = 200       # evenly spaced along the perimeter
    sample_radius: float = 0.04        # r.u.: cloud points counted around a sample
    sample_max_points: int = 2         # a sample with more cloud points than this is dropped

    # -- alternatives of seed 000
    dbscan_eps: float = 0.06           # r.u.; DBSCAN neighbourhood
    dbscan_min_samples: int = 8
    outside_margin: float = 0.08       # r.u.: points closer than this to the outline are walls
    alpha_radius: float = 0.08         # r.u.: alpha outline keeps triangles of smaller circumradius
    outline_simplify: float = 0.04     # r.u.: Douglas-Peucker tolerance of the alpha outline
    min_concave_depth: float = 0.03    # r.u.: shallower dents of the outline are not vertices

    # -- gap method (beyond seed 000; see gaps.py). Defaults chosen on the simulator benchmark
    #    (bench/bench_exit_finder.py), not on the real files.
    gap_viewpoint: str = "origin"      # where the map was seen from: "origin" of the input (an
    #                                    ORB-SLAM map's first camera; falls back to "estimate"
    #                                    outside the cloud), "estimate" (fewest hidden points),
    #                                    or "centroid" (mean of the points)
    gap_viewpoint_step: float = 0.2    # r.u.: first grid step of the viewpoint search
    gap_viewpoint_levels: int = 3      # grid refinements (each 2.5 times finer)
    gap_viewpoint_points: int = 3000   # points used by the search (a random subset)
    gap_viewpoint_bins: int = 180      # bearings used by the search
    gap_angle_bins: int = 360          # bearings around the room centre
    gap_pool_bins: int = 1             # each bearing's histogram also counts this many on each side
    gap_log_bin: float = 0.025         # log-range histogram bin (a 2.5% step in range)
    gap_log_smooth: float = 2.0        # Gaussian smoothing of that histogram (bins)
    gap_min_range: float = 0.05        # r.u.: nearer points are ignored by the profile
    gap_max_range: float = 5.0         # r.u.: farther points are ignored by the profile
    gap_surface_share: float = 0.8     # first peak with this share of the bearing's highest peak
                                       # (lower: depth streaks in front of a thick wall open
                                       # false notches; bench and live runs say 0.8)
    gap_min_surface_points: float = 3.0  # ... and about this many points is the surface
    gap_jump: float = 0.2              # a surface jump by more than this share of range: a jamb
    gap_jamb_bins: int = 2             # a jamb's wall runs on this many bearings beside it, and
    #                                    its jump may take this many (pooling smears it)
    gap_extension_bins: int = 8        # a wall is extended past a jamb from this many bearings
    gap_grazing: float = 2.0           # a wall seen this edge-on (extension > this x range) is
    #                                    not extended; any inward jump ends its opening
    gap_max_rights: int = 2            # right jambs tried per left jamb, nearest first (1: only
    #                                    the first jump back; 2 on 400 bench rooms: 207 of 263
    #                                    hits instead of 202)
    gap_notch_share: float = 0.7       # share of a notch's bearings that must lie beyond the door
    gap_beyond_margin: float = 0.15    # "through": beyond the bridge by > this share of range
    gap_min_width: float = 0.05        # r.u.: narrower notches are noise
    gap_max_width: float = 0.7         # r.u.: wider notches are not doors
    gap_max_span_deg: float = 90.0     # a notch spans at most this many degrees of bearing
    gap_door_width: float = 0.2        # r.u.: the most likely door width (about 1 m in a room of
    #                                    4-5 m radius); the confidence prefers widths near it
    gap_door_width_sigma: float = 0.5  # spread of that preference in log width
    gap_beyond_points: float = 5.0     # points seen through an opening: evidence (n + 1) /
    #                                    (n + 1 + this), so about this many make it half sure
    gap_cover_weight: float = 0.5      # confidence x (1 - this x the share of the opening's
    #                                    bearings with fewer than gap_min_surface_points seen
    #                                    through them): an exit shows its backdrop across its
    #                                    width, an inner door a few far objects (0: off)
    gap_occluder_share: float = 0.7    # a jamb whose bearings (from gap_occluder_offset bearings
    gap_occluder_offset: int = 1       # away from the opening on) have more than this share of
    #                                    their points far behind the surface is a box or a wall
    #                                    end in front of a wall, not a door frame (1: never)
    gap_spread_free: float = 0.5       # depth spread of the points seen through a door (10-90 %
    gap_spread_weight: float = 2.0     # percentile, over the door's range) beyond this lowers its
    #                                    confidence by 1 / (1 + weight x excess): through an exit
    #                                    the camera sees what stands outside, through an inner
    #                                    door a room's walls at many depths (0: off; 2 on 400
    #                                    bench rooms: 202 of 263 hits instead of 197)
    gap_centre_min_points: int = 5     # the door centre follows the mean bearing of the points
    #                                    seen through it when at least this many were (0: never)
    gap_outline_smooth: int = 3        # outline: running median over this many bearings each side
    gap_max_exits: int = 5             # exits reported
    # -- ranked method (beyond seed 000; see doors.py and ranker.py): the door candidates of the
    #    gaps method at three bearing resolutions and the gaps in RANSAC walls, scored by a model
    #    learned on simulator rooms (bench/train_door_ranker.py)
    rank_model: str = ""               # the model's JSON file; "": the one shipped with the package
    rank_merge_radius: float = 0.1     # r.u.: a candidate this close to a better one is that door
    rank_min_probability: float = 0.1  # candidates the model rates below this are not reported:
    #                                    a closed room gives no exit (on the 400 bench rooms every
    #                                    hit was rated 0.14 or more; closed test rooms lower)
    external_weight: float = 0.5       # confidence of a door gap given by the feature extractor
    external_match: float = 0.15       # r.u.: own and external gaps closer than this are one door
    auto_min_confidence: float = 0.05  # auto: a ranked answer below this falls back to the seed
    #                                    (below rank_min_probability, so by default auto takes any
    #                                    exit ranked reports, and the seed when it reports none)

    def validate(self):
        """Raise ValueError naming the first invalid parameter."""
        def positive(name, strict=True):
            value = getattr(self, name)
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and \
                math.isfinite(value) and (value > 0 if strict else value >= 0)
            if not ok:
                raise ValueError(f"{name} must be a finite number {'>' if strict else '>='} 0, "
                                 f"got {value!r}")

        def integer(name, minimum):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
                raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")

        integer("min_points", 8)
        integer("round_decimals", 0)
        integer("ipcl_min_neighbours", 0)
        integer("ipcl_rounds", 0)
        integer("ransac_lines", 4)
        integer("ransac_iterations", 1)
        integer("ransac_max_eval_points", 10)
        integer("seed", 0)
        integer("rpcl_min_neighbours", 1)
        integer("perimeter_samples", 8)
        integer("sample_max_points", 0)
        integer("dbscan_min_samples", 1)
        integer("gap_angle_bins", 16)
        integer("gap_viewpoint_levels", 0)
        integer("gap_viewpoint_points", 10)
        integer("gap_viewpoint_bins", 16)
        integer("gap_pool_bins", 0)
        integer("gap_jamb_bins", 0)
        integer("gap_max_rights", 1)
        integer("gap_extension_bins", 1)
        integer("gap_max_exits", 1)
        integer("gap_outline_smooth", 0)
        integer("gap_occluder_offset", 0)
        integer("gap_centre_min_points", 0)
        for name in ("collinear_ratio", "ipcl_radius", "line_near_dist", "rpcl_radius",
                     "distinct_offset", "max_corner_dist", "min_room_area", "sample_radius",
                     "dbscan_eps", "outside_margin", "alpha_radius", "outline_simplify",
                     "gap_viewpoint_step", "gap_grazing", "gap_log_bin", "gap_log_smooth",
                     "gap_min_range", "gap_max_range",
                     "gap_min_width", "gap_max_width", "gap_max_span_deg", "gap_door_width",
                     "gap_door_width_sigma", "gap_beyond_points", "external_match",
                     "rank_merge_radius"):
            positive(name)
        for name in ("min_concave_depth", "gap_beyond_margin", "gap_jump",
                     "gap_min_surface_points", "gap_spread_free", "gap_spread_weight"):
            positive(name, strict=False)
        if not 0 < self.scale_percentile <= 100:
            raise ValueError(f"scale_percentile must be in (0, 100], got {self.scale_percentile}")
        if self.gap_viewpoint not in VIEWPOINTS:
            raise ValueError(f"gap_viewpoint must be one of {', '.join(VIEWPOINTS)}, got "
                             f"{self.gap_viewpoint!r}")
        if self.line_score not in LINE_SCORES:
            raise ValueError(f"line_score must be one of {', '.join(LINE_SCORES)}, got "
                             f"{self.line_score!r}")
        for name in ("distinct_angle_deg", "min_corner_angle_deg"):
            if not 0 <= getattr(self, name) < 90:
                raise ValueError(f"{name} must be in [0, 90), got {getattr(self, name)}")
        for name in ("gap_surface_share", "gap_notch_share", "external_weight", "gap_cover_weight",
                     "gap_occluder_share", "auto_min_confidence", "rank_min_probability"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if not isinstance(self.rank_model, str):
            raise ValueError(f"rank_model must be a file name (str), got {self.rank_model!r}")
        if self.gap_min_width >= self.gap_max_width:
            raise ValueError("gap_min_width must be < gap_max_width")
        if self.gap_min_range >= self.gap_max_range:
            raise ValueError("gap_min_range must be < gap_max_range")
        if not isinstance(self.ransac_refit, bool) or not isinstance(self.distinct_lines, bool) \
                or not isinstance(self.drop_non_finite, bool):
            raise ValueError("ransac_refit, distinct_lines and drop_non_finite must be booleans")
        return self
