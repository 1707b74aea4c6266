"""cartographer: one map fragment per SLAM map, kept across map switches and saved as it goes."""
import threading

import rospy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

from sparse_nav.cartographer import Cartographer, CartographerConfig, FragmentError
from sparse_nav.msg import SlamState
from sparse_nav.ros.conversions import CloudError, cloud_to_points, points_to_cloud
from sparse_nav.srv import ListFragments, ListFragmentsResponse, MapFile, MapFileResponse
from sparse_nav.ros.params import locked, read_fields


def _config_from_params():
    cfg = CartographerConfig()
    read_fields(cfg, ("map_dir", "save_period_s", "merge_voxel_m", "max_points"))
    cfg.frame = rospy.get_param("~map_frame", cfg.frame)
    cfg.validate()
    return cfg


class CartographerNode:
    """Glue between slam/state, cloud/filtered and the ROS-free Cartographer."""

    def __init__(self):
        self.lock = threading.RLock()
        self.carto = Cartographer(_config_from_params())
        self.bad_inputs = 0
        self.save_errors = 0
        self.last_event = ""
        loaded = self.carto.reload()
        rospy.loginfo("cartographer: %d fragments loaded from %s (next session %d)",
                      len(loaded), self.carto.store.map_dir, self.carto.session)
        if self.carto.removed_temporaries:
            rospy.logwarn("cartographer: removed %d temporary files of interrupted writes",
                          self.carto.removed_temporaries)
        for error in sorted(self.carto.load_errors.values()):
            rospy.logerr("cartographer: refused %s", error)

        self.fragment_pub = rospy.Publisher("cartographer/fragment", PointCloud2, queue_size=1,
                                            latch=True)
        self.diag_pub = rospy.Publisher("/diagnostics", DiagnosticArray, queue_size=10)
        rospy.Subscriber("slam/state", SlamState, self._on_state, queue_size=20)
        rospy.Subscriber("cloud/filtered", PointCloud2, self._on_cloud, queue_size=2)
        rospy.Service("~save", MapFile, self._on_save)
        rospy.Service("~load", MapFile, self._on_load)
        rospy.Service("~list", ListFragments, self._on_list)
        period = min(1.0, self.carto.cfg.save_period_s / 2.0)
        rospy.Timer(rospy.Duration(period), self._on_timer)
        rospy.Timer(rospy.Duration(1.0), self._on_diagnostics)
        rospy.on_shutdown(self._on_shutdown)

    def _bad_input(self, what):
        self.bad_inputs += 1
        rospy.logerr_throttle(5.0, f"cartographer: ignoring {what}")

    def _guarded_save(self, action, *args):
        """Runs a saving call; a failing disk is reported, never fatal."""
        try:
            return action(*args)
        except (OSError, FragmentError) as exc:
            self.save_errors += 1
            rospy.logerr_throttle(5.0, f"cartographer: saving failed: {exc}")
            return None

    @locked
    def _on_state(self, msg):
        events = self._guarded_save(self.carto.on_slam_state, msg.state, msg.map_index,
                                    msg.header.stamp.to_sec())
        for event in events or []:
            self.last_event = event
            rospy.loginfo("cartographer: %s", event)

    @locked
    def _on_cloud(self, msg):
        if msg.header.frame_id != self.carto.cfg.frame:
            self._bad_input(f"cloud/filtered in frame {msg.header.frame_id!r}, expected "
                            f"{self.carto.cfg.frame!r}")
            return
        try:
            self.carto.on_cloud(cloud_to_points(msg), msg.header.stamp.to_sec())
        except (CloudError, FragmentError) as exc:
            self._bad_input(f"cloud/filtered: {exc}")

    @locked
    def _on_timer(self, _event):
        self._guarded_save(self.carto.save_due, rospy.Time.now().to_sec())

    @locked
    def _on_shutdown(self):
        self._guarded_save(self.carto.flush, rospy.Time.now().to_sec())

    @locked
    def _on_save(self, req):
        try:
            n = self.carto.save_as(req.name, rospy.Time.now().to_sec())
        except (FragmentError, OSError) as exc:
            return MapFileResponse(success=False, message=str(exc))
        return MapFileResponse(success=True, message=f"saved {n} points as {req.name!r}")

    @locked
    def _on_load(self, req):
        try:
            points, meta = self.carto.load(req.name)
        except (FragmentError, OSError) as exc:
            rospy.logerr("cartographer: load refused: %s", exc)
            return MapFileResponse(success=False, message=str(exc))
        header = Header(stamp=rospy.Time.now(), frame_id=meta.get("frame", self.carto.cfg.frame))
        self.fragment_pub.publish(points_to_cloud(points, header))
        return MapFileResponse(success=True, message=f"loaded {len(points)} points of "
                                                     f"{req.name!r}, published on "
                                                     "cartographer/fragment")

    @locked
    def _on_list(self, _req):
        try:
            listing = self.carto.list()
        except OSError as exc:
            return ListFragmentsResponse(success=False, message=str(exc))
        refused = sum(1 for _, n, _ in listing if n is None)
        return ListFragmentsResponse(
            names=[name for name, _, _ in listing],
            n_points=[n or 0 for _, n, _ in listing],
            errors=[error for _, _, error in listing], success=True,
            message=f"{len(listing)} fragments in {self.carto.store.map_dir}, {refused} refused")

    @locked
    def _on_diagnostics(self, _event):
        current = self.carto.current
        status = DiagnosticStatus()
        status.name = "cartographer"
        status.hardware_id = "map"
        problems = self.save_errors or self.carto.load_errors
        status.level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        status.message = self.last_event or "waiting for a SLAM map"
        status.values = [KeyValue(k, str(v)) for k, v in (
            ("map_dir", self.carto.store.map_dir), ("session", self.carto.session),
            ("current_fragment", current.name if current else ""),
            ("current_points", len(current.points) if current else 0),
            ("fragments_this_session", len(self.carto.fragments)),
            ("fragments_loaded", len(self.carto.library)),
            ("refused_files", len(self.carto.load_errors)), ("save_errors", self.save_errors),
            ("bad_inputs", self.bad_inputs))]
        msg = DiagnosticArray()
        msg.header.stamp = rospy.Time.now()
        msg.status = [status]
        self.diag_pub.publish(msg)


def main():
    rospy.init_node("cartographer")
    try:
        CartographerNode()
    except (ValueError, OSError) as exc:
        rospy.logfatal(f"cartographer: {exc}")
        raise SystemExit(1)
    rospy.spin()
