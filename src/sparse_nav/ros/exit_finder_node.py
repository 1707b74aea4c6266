"""exit_finder: the room's exit in the filtered SLAM cloud, on request or periodically.

ROS glue around :func:`sparse_nav.exit_finder.find_exit`: the latest ``cloud`` (any frame TF can
bring into ``map_frame``, whose z is up; the launch file connects the bridge's metric SLAM points)
is kept; the finder runs on it when ``~find_exit``
is called, or every ``period_s`` when a new cloud has come. Each run publishes the ranked
candidates with their status (latched), markers, and, when an exit was found, the best one on
``exit``. A malformed cloud is refused and the last good one kept; a cloud that holds no room
gives a status saying why, and no exit.
"""
import dataclasses
import threading

import numpy as np
import rospy
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PointStamped
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from sparse_nav.exit_finder import (DEFAULT_METHOD, METHODS, ExitFinderConfig, ExitFinderError,
                                    find_exit)
from sparse_nav.msg import ExitCandidates, Features
from sparse_nav.ros.conversions import CloudError, cloud_to_points, transform_to_matrix
from sparse_nav.srv import FindExit, FindExitResponse
from sparse_nav.ros.params import read_fields

VIEWPOINTS = ("origin", "robot", "estimate", "centroid")
_TF_ERRORS = (tf2_ros.LookupException, tf2_ros.ConnectivityException,
              tf2_ros.ExtrapolationException)


def _config_from_params():
    cfg = ExitFinderConfig()
    read_fields(cfg, ("min_points", "gap_max_exits", "seed", "rank_model", "rank_min_probability"))
    return cfg.validate()


class ExitFinderNode:
    """Owns one finder configuration and the latest good cloud (in map_frame)."""

    def __init__(self):
        self.cfg = _config_from_params()
        self.method = rospy.get_param("~method", DEFAULT_METHOD)
        if self.method not in METHODS:
            raise ValueError(f"~method must be one of {', '.join(METHODS)}, got {self.method!r}")
        self.viewpoint = rospy.get_param("~viewpoint", "origin")
        if self.viewpoint not in VIEWPOINTS:
            raise ValueError(f"~viewpoint must be one of {', '.join(VIEWPOINTS)}, got "
                             f"{self.viewpoint!r}")
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.base_frame = rospy.get_param("~base_frame", "base_link")
        self.period_s = float(rospy.get_param("~period_s", 0.0))
        self.tf_timeout_s = float(rospy.get_param("~tf_timeout_s", 0.5))
        if not (np.isfinite(self.period_s) and self.period_s >= 0):
            raise ValueError(f"~period_s must be >= 0, got {self.period_s}")
        self.use_door_gaps = bool(rospy.get_param("~use_door_gaps", True))
        self.door_gaps_max_age_s = float(rospy.get_param("~door_gaps_max_age_s", 30.0))

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        # Subscriber, timer and service callbacks run on their own threads.
        self.lock = threading.Lock()
        self.run_lock = threading.Lock()
        self.points = None
        self.stamp = rospy.Time(0)
        self.received_at = None
        self.cloud_seq = 0
        self.run_seq = 0
        self.n_clouds = 0
        self.n_bad_clouds = 0
        self.n_runs = 0
        self.last = None
        self.door_gaps = None
        self.door_gaps_stamp = None

        self.exit_pub = rospy.Publisher("exit", PointStamped, queue_size=1, latch=True)
        self.cand_pub = rospy.Publisher("exit_candidates", ExitCandidates, queue_size=1,
                                        latch=True)
        self.marker_pub = rospy.Publisher("exit_finder/markers", MarkerArray, queue_size=1,
                                          latch=True)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=5)
        rospy.Subscriber("cloud", PointCloud2, self._on_cloud, queue_size=1,
                         buff_size=2 ** 24)
        if self.use_door_gaps:
            rospy.Subscriber("features", Features, self._on_features, queue_size=2)
        rospy.Service("~find_exit", FindExit, self._on_find_exit)
        self._publish(self._candidates(ExitCandidates.STATUS_NO_CLOUD,
                                       "no cloud received yet", rospy.Time(0)))
        if self.period_s > 0:
            rospy.Timer(rospy.Duration(self.period_s), self._on_timer)
        rospy.Timer(rospy.Duration(1.0), self._on_diagnostics)

    def _on_cloud(self, msg):
        try:
            points = cloud_to_points(msg)
            points = self._to_map(points, msg.header)
        except (CloudError, ValueError) as exc:
            with self.lock:
                self.n_bad_clouds += 1
            rospy.logerr_throttle(5.0, f"exit_finder: refusing a cloud: {exc}; keeping the last "
                                       f"good one")
            self._publish(self._candidates(ExitCandidates.STATUS_BAD_INPUT,
                                           f"cloud refused: {exc}", msg.header.stamp))
            return
        with self.lock:
            self.points, self.stamp = points, msg.header.stamp
            self.received_at = rospy.Time.now()
            self.cloud_seq += 1
            self.n_clouds += 1

    def _on_features(self, msg):
        """Keeps the feature extractor's latest doors as (x, y, width) in map_frame."""
        if not msg.ok:
            return
        try:
            centres = np.array([[d.center.x, d.center.y, d.center.z] for d in msg.doors],
                               dtype=float).reshape(-1, 3)
            widths = np.array([d.width_m for d in msg.doors], dtype=float)
            centres = self._to_map(centres, msg.header)
        except ValueError as exc:
            rospy.logwarn_throttle(10.0, f"exit_finder: ignoring door gaps: {exc}")
            return
        good = np.isfinite(centres).all(axis=1) & np.isfinite(widths) & (widths > 0)
        with self.lock:
            self.door_gaps = np.column_stack([centres[good, :2], widths[good]])
            self.door_gaps_stamp = rospy.Time.now()

    def _recent_door_gaps(self):
        """The latest door gaps if younger than door_gaps_max_age_s, else None."""
        with self.lock:
            gaps, stamp = self.door_gaps, self.door_gaps_stamp
        if gaps is None or not len(gaps) or \
                (rospy.Time.now() - stamp).to_sec() > self.door_gaps_max_age_s:
            return None
        return gaps

    def _to_map(self, points, header):
        """(N, 3) points of the header's frame in map_frame; ValueError for an unknown frame."""
        frame = header.frame_id.lstrip("/")
        if not frame:
            raise ValueError("the cloud has no frame_id")
        if frame == self.map_frame:
            return points
        try:
            tf = self.tf_buffer.lookup_transform(self.map_frame, frame, rospy.Time(0),
                                                 rospy.Duration(self.tf_timeout_s))
        except _TF_ERRORS as exc:
            raise ValueError(f"no TF from {frame!r} to {self.map_frame!r}: {exc}") from None
        t = transform_to_matrix(tf.transform)
        return points @ t[:3, :3].T + t[:3, 3]

    def _on_timer(self, _event):
        with self.lock:
            fresh = self.cloud_seq != self.run_seq
        if fresh:
            self.run(self.method, self.viewpoint)

    def _on_find_exit(self, req):
        method = req.method or self.method
        viewpoint = req.viewpoint or self.viewpoint
        if method not in METHODS or viewpoint not in VIEWPOINTS:
            why = (f"unknown method {method!r}; choose one of {', '.join(METHODS)}"
                   if method not in METHODS else
                   f"unknown viewpoint {viewpoint!r}; choose one of {', '.join(VIEWPOINTS)}")
            cand = self._candidates(ExitCandidates.STATUS_BAD_INPUT, why, rospy.Time.now())
            return FindExitResponse(success=False, candidates=cand)
        cand = self.run(method, viewpoint, any_probability=req.any_probability)
        return FindExitResponse(success=cand.status == ExitCandidates.STATUS_OK,
                                candidates=cand)

    def run(self, method, viewpoint, any_probability=False):
        """Runs the finder on the latest cloud from viewpoint (one of VIEWPOINTS), publishes
        and returns the ExitCandidates; any_probability: rank_min_probability not applied."""
        with self.run_lock:
            with self.lock:
                points, stamp, seq = self.points, self.stamp, self.cloud_seq
                self.run_seq = seq
                self.n_runs += 1
            if points is None:
                cand = self._candidates(ExitCandidates.STATUS_NO_CLOUD,
                                        "no good cloud received yet", rospy.Time.now())
            else:
                cand = self._find(points, stamp, method, viewpoint, any_probability)
            self._publish(cand)
            return cand

    def _robot_xy(self):
        """(x, y) of base_frame in map_frame, or None (then the finder looks from the origin)."""
        try:
            tf = self.tf_buffer.lookup_transform(self.map_frame, self.base_frame, rospy.Time(0),
                                                 rospy.Duration(self.tf_timeout_s))
        except _TF_ERRORS as exc:
            rospy.logwarn_throttle(10.0, f"exit_finder: no robot pose ({exc}); looking from the "
                                         f"map origin")
            return None
        return (tf.transform.translation.x, tf.transform.translation.y)

    def _find(self, points, stamp, method, viewpoint, any_probability):
        cfg = dataclasses.replace(
            self.cfg, gap_viewpoint=viewpoint if viewpoint != "robot" else "origin",
            rank_min_probability=0.0 if any_probability else self.cfg.rank_min_probability)
        robot_xy = self._robot_xy() if viewpoint == "robot" else None
        try:
            result = find_exit(points, method=method, config=cfg, up_axis="z",
                               viewpoint=robot_xy, door_gaps=self._recent_door_gaps())
        except ExitFinderError as exc:
            rospy.logwarn_throttle(5.0, f"exit_finder: {exc.status}: {exc}")
            cand = self._candidates(exc.status, str(exc), stamp)
            cand.n_points_in = len(points)
            return cand
        cand = self._candidates(result.status, result.reason, stamp)
        cand.method = result.method
        cand.exits = [Point(x=x, y=y, z=0.0) for x, y, _ in result.exits]
        cand.scores = [s for _, _, s in result.exits]
        cand.room_outline = [Point(x=x, y=y, z=0.0) for x, y in result.room_corners]
        cand.n_points_in = result.n_points_in
        cand.n_points_used = result.n_points_used
        cand.runtime_s = result.runtime_s
        if result.n_dropped_non_finite:
            cand.reason += f" ({result.n_dropped_non_finite} non-finite points dropped)"
        return cand

    def _candidates(self, status, reason, stamp):
        cand = ExitCandidates(status=status, reason=reason)
        cand.header.frame_id = self.map_frame
        cand.header.stamp = stamp
        return cand

    def _publish(self, cand):
        with self.lock:
            self.last = cand
        self.cand_pub.publish(cand)
        self.marker_pub.publish(self._markers(cand))
        if cand.status == ExitCandidates.STATUS_OK and cand.exits:
            self.exit_pub.publish(PointStamped(header=cand.header, point=cand.exits[0]))

    def _markers(self, cand):
        """Room outline, the candidates (best green, others orange, size by score), scores."""
        clear = Marker(action=Marker.DELETEALL)
        clear.header = cand.header
        out = [clear]
        if cand.room_outline:
            m = self._marker(cand, "room_outline", 0, Marker.LINE_STRIP, (0.1, 0.3, 1.0))
            m.scale.x = 0.05
            m.points = list(cand.room_outline) + [cand.room_outline[0]]
            out.append(m)
        for k, (p, score) in enumerate(zip(cand.exits, cand.scores)):
            colour = (0.1, 0.9, 0.1) if k == 0 else (1.0, 0.6, 0.0)
            m = self._marker(cand, "exits", k, Marker.SPHERE, colour)
            m.pose.position = Point(x=p.x, y=p.y, z=0.3)
            size = 0.25 + 0.35 * float(score)
            m.scale.x = m.scale.y = m.scale.z = size
            out.append(m)
            t = self._marker(cand, "scores", k, Marker.TEXT_VIEW_FACING, (1.0, 1.0, 1.0))
            t.pose.position = Point(x=p.x, y=p.y, z=0.3 + size)
            t.scale.z = 0.25
            t.text = f"exit {k}: {score:.2f}"
            out.append(t)
        return MarkerArray(markers=out)

    @staticmethod
    def _marker(cand, ns, mid, kind, rgb):
        m = Marker(ns=ns, id=mid, type=kind, action=Marker.ADD)
        m.header = cand.header
        m.pose.orientation.w = 1.0
        m.color = ColorRGBA(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0)
        return m

    def _on_diagnostics(self, _event):
        with self.lock:
            cand, received_at = self.last, self.received_at
            counts = (self.n_clouds, self.n_bad_clouds, self.n_runs)
        status = DiagnosticStatus(name="exit_finder", hardware_id="exit_finder")
        if cand.status == ExitCandidates.STATUS_OK:
            status.level = DiagnosticStatus.OK
        elif cand.status == ExitCandidates.STATUS_BAD_INPUT:
            status.level = DiagnosticStatus.ERROR
        else:
            status.level = DiagnosticStatus.WARN
        status.message = f"{cand.status}: {cand.reason}"
        age = (rospy.Time.now() - received_at).to_sec() if received_at is not None else -1.0
        status.values = [KeyValue(k, str(v)) for k, v in (
            ("method", cand.method or self.method), ("exits", len(cand.exits)),
            ("best_score", f"{cand.scores[0]:.2f}" if cand.scores else "-"),
            ("points_in", cand.n_points_in), ("points_used", cand.n_points_used),
            ("runtime_s", f"{cand.runtime_s:.3f}"), ("cloud_age_s", f"{age:.1f}"),
            ("clouds", counts[0]), ("bad_clouds", counts[1]), ("runs", counts[2]))]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = rospy.Time.now()
        self.diag_pub.publish(msg)


def main():
    rospy.init_node("exit_finder")
    try:
        ExitFinderNode()
    except ValueError as exc:
        rospy.logfatal(f"exit_finder: {exc}")
        raise SystemExit(1)
    rospy.spin()
