"""The planner node's sensors: point clouds into the collision scene, one occupancy octree per sensor.

Each topic of ``point_cloud_topics`` (sensor_msgs/PointCloud2, best effort, depth 1: the newest
cloud) has a frame (``point_cloud_frames``) and a pose in the base frame (``point_cloud_poses``, 7
values x y z qx qy qz qw per topic; there is no TF). A cloud is used when its ``frame_id`` is the
base frame (points taken as they are) or the sensor's frame (taken into the base frame by the
pose); another frame is refused with a rate-limited warning, as are clouds that cannot be read
(:mod:`.point_clouds`), clouds of more than ``max_cloud_points`` points, and clouds before a valid
``/joint_states`` (the robot's own image cannot be filtered out without it). A sensor's clouds
arriving faster than ``max_cloud_rate`` are skipped (counted in the map's line).

An accepted cloud becomes its sensor's map (:func:`~geodesic_planner.core.point_cloud.cloud_map`:
NaN points skipped, the robot at the latest joint state removed with its bodies grown by
``self_filter_padding``, the voxels of ``octree_resolution``) and replaces the sensor's previous map
in the collision model, in one step under the node's configuration lock: the octree is one more
scene object, named after the topic, in every plan's check. The maths runs in the library; the
callbacks (one at a time, in a group of their own) only parse, call and swap.

Plans (:meth:`SensorMaps.check`): with sensors configured, every sensor must have delivered a cloud
less than ``max_cloud_age`` s ago (time of arrival); else the plan is refused (PLANNING_FAILED,
naming the sensor and the age), or, with ``stale_clouds: warn``, planned against the maps there
are, with the warning in the log and at the head of the reply's message.

``~/octree_markers`` (visualization_msgs/MarkerArray, reliable, transient local): every map's
occupied voxels as a CUBE_LIST (namespace ``octree``), built only while a reader is matched, and
published again whenever a map changes or a reader matches.
"""
from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import Point, Vector3
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from ..core.collision import CollisionModel
from ..core.errors import GeodesicPlannerError, quoted
from ..core.point_cloud import CloudMap, SelfFilter, Sensor, StaleMapError, cloud_map, map_summary, sensors, with_map
from .joint_states import RateLimitedWarnings
from .point_clouds import cloud_points
from .scene_msgs import marker_ids

__all__ = ['MARKER_NS', 'SensorMaps', 'node_sensors']

#: Marker namespace of the maps' voxels, and their colour (r, g, b, a).
MARKER_NS = 'octree'
VOXEL_COLOR = (0.9, 0.3, 0.3, 0.8)
#: change(model) -> new model, applied under the node's configuration lock (planner_node).
Update = Callable[[Callable[[CollisionModel], CollisionModel]], CollisionModel]


def node_sensors(node: Node) -> tuple[Sensor, ...]:
    """The sensors of the node's parameters, topics resolved (ConfigError: bad values)."""
    topics = [node.resolve_topic_name(t) if t else t for t in node.get_parameter('point_cloud_topics').value or []]
    return sensors(topics, list(node.get_parameter('point_cloud_frames').value or []),
                   list(node.get_parameter('point_cloud_poses').value or []))


@dataclass
class _State:
    """One sensor's latest map and counts."""

    found: CloudMap | None = None
    arrived: float = -math.inf        # monotonic time of the cloud of ``found``
    skipped: int = 0                  # clouds over max_cloud_rate
    refused: int = 0


class SensorMaps:
    """Subscriptions, maps and markers of the node's sensors.

    Args:
        node: the planner node (parameters, log, clock).
        sensors: from :func:`node_sensors`.
        update: applies a change to the configuration's collision model (raises
            GeodesicPlannerError when there is none).
        current: the current collision model and base frame, or None.
        joints: the latest valid joint state for the current model, or None.
        warnings: the node's rate-limited warnings.
    """

    def __init__(self, node: Node, sensors: tuple[Sensor, ...], update: Update,
                 current: Callable[[], tuple[CollisionModel, str] | None],
                 joints: Callable[[], np.ndarray | None], warnings: RateLimitedWarnings) -> None:
        self._node, self.sensors, self._update = node, sensors, update
        self._current, self._joints, self._warnings = current, joints, warnings
        self._states = {s.topic: _State() for s in sensors}
        self._lock = threading.Lock()
        self._filter: tuple[object, float, SelfFilter] | None = None
        self.group = MutuallyExclusiveCallbackGroup()
        qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
        self.subscriptions = [node.create_subscription(PointCloud2, s.topic, functools.partial(self._on_cloud, s),
                                                       qos, callback_group=self.group) for s in sensors]
        self.marker_pub = node.create_publisher(
            MarkerArray, '~/octree_markers',
            QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL),
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        self.markers_published = 0

    def _param(self, name: str) -> float:
        return float(self._node.get_parameter(name).value)

    # ------------------------------------------------------------------ clouds
    def _on_cloud(self, sensor: Sensor, msg: PointCloud2) -> None:
        state = self._states[sensor.topic]
        now = time.monotonic()
        if now - state.arrived < 1.0 / self._param('max_cloud_rate'):
            state.skipped += 1
            return
        try:
            self._take(sensor, msg, state, now)
        except GeodesicPlannerError as err:
            state.refused += 1
            self._warnings.warn(f'cloud {sensor.topic}', f'ignoring a cloud on {sensor.topic}: {err}')
        except Exception as err:  # noqa: BLE001 - boundary: a cloud never ends the node
            state.refused += 1
            self._warnings.warn(f'cloud {sensor.topic}', f'ignoring a cloud on {sensor.topic}: internal error: '
                                f'{type(err).__name__}: {err}')

    def _take(self, sensor: Sensor, msg: PointCloud2, state: _State, now: float) -> None:
        current = self._current()
        if current is None:
            raise GeodesicPlannerError('no collision model (no robot yet, or collision_check is false)')
        model, base = current
        frame = msg.header.frame_id
        if frame not in (base, sensor.frame):
            raise GeodesicPlannerError(f'frame_id {quoted(frame)} is neither the base frame {quoted(base)} nor the '
                                       f'sensor frame {quoted(sensor.frame)} (point_cloud_frames; no TF here)')
        points = cloud_points(msg, int(self._node.get_parameter('max_cloud_points').value))
        q = self._joints()
        if q is None:
            raise GeodesicPlannerError('no valid /joint_states yet: the robot cannot be filtered out of the cloud')
        found = cloud_map(sensor.topic, points, sensor.pose if frame != base else np.eye(4),
                          self._param('octree_resolution'), self_filter=self._self_filter(model), q=q)
        self._update(lambda m: with_map(m, sensor.topic, found.object))
        with self._lock:
            state.found, state.arrived = found, now
        if self.marker_pub.get_subscription_count() > 0:
            self._publish_markers()

    def _self_filter(self, model: CollisionModel) -> SelfFilter:
        """The filter for the model's robot bodies and the padding (kept while both are unchanged)."""
        pad = self._param('self_filter_padding')
        cached = self._filter
        if cached is None or cached[0] is not model.robot_bodies or cached[1] != pad:
            cached = self._filter = (model.robot_bodies, pad, SelfFilter(model, pad))
        return cached[2]

    # ------------------------------------------------------------------ plans
    def check(self, model: CollisionModel | None) -> str:
        """'' when every sensor's map in ``model`` (the plan's) is fresh; the warning when not and
        ``stale_clouds`` is warn.

        Raises:
            StaleMapError: a sensor's cloud is older than ``max_cloud_age``, none came yet, or its
                map is not in ``model`` (the model was rebuilt since, e.g. by a parameter change).
        """
        if not self.sensors or model is None:
            return ''
        limit, now = self._param('max_cloud_age'), time.monotonic()
        present = {o.id for o in model.objects}
        with self._lock:
            states = [(topic, st.arrived, st.found) for topic, st in self._states.items()]
        stale = []
        for topic, arrived, found in states:
            if math.isinf(arrived):
                stale.append(f'no cloud from {topic} yet')
            elif not now - arrived <= limit:
                stale.append(f'the map of {topic} is {now - arrived:.3f} s old')
            elif found is not None and found.object is not None and topic not in present:
                stale.append(f'no map of {topic} in the collision model (rebuilt since its last cloud)')
        if not stale:
            return ''
        said = '; '.join(stale)
        if self._node.get_parameter('stale_clouds').value == 'warn':
            return f'planned against stale maps ({said}; max_cloud_age {limit:g} s, stale_clouds warn)'
        raise StaleMapError(f'point clouds too old: {said} (max_cloud_age {limit:g} s); refused '
                            '(stale_clouds: warn plans against the last maps)')

    # ------------------------------------------------------------------ listing
    def ids(self) -> frozenset[str]:
        """The sensors' map names (reserved in the scene services)."""
        return frozenset(self._states)

    def describe(self, sensor_id: str) -> str:
        """A map's line for ``~/list_collision_objects``: points, voxels, the cloud's age."""
        with self._lock:
            st = self._states.get(sensor_id)
            found, arrived = (st.found, st.arrived) if st is not None else (None, -math.inf)
            counts = '' if st is None else f'; {st.skipped} clouds skipped (max_cloud_rate), {st.refused} refused'
        if found is None:
            return f'octree: no cloud yet{counts}'
        return map_summary(found, time.monotonic() - arrived) + counts

    # ------------------------------------------------------------------ markers
    def _on_matched(self, status: object) -> None:
        if getattr(status, 'current_count_change', 0) > 0:
            self._publish_markers()

    def _publish_markers(self) -> None:
        current = self._current()
        frame = current[1] if current is not None else ''
        with self._lock:
            maps = [(t, st.found) for t, st in self._states.items()]
        header = Header(frame_id=frame, stamp=self._node.get_clock().now().to_msg())
        markers = [Marker(header=header, ns=MARKER_NS, action=Marker.DELETEALL)]
        ids = marker_ids([t for t, _ in maps])
        r, g, b, a = VOXEL_COLOR
        for topic, found in maps:
            if found is None or found.object is None:
                continue
            res = found.resolution
            centres = np.asarray(found.object.shape.vertices, dtype=float)
            markers.append(Marker(header=header, ns=MARKER_NS, id=ids[topic], type=Marker.CUBE_LIST,
                                  action=Marker.ADD, scale=Vector3(x=res, y=res, z=res),
                                  color=ColorRGBA(r=r, g=g, b=b, a=a),
                                  points=[Point(x=x, y=y, z=z) for x, y, z in centres.tolist()]))
            markers[-1].pose.orientation.w = 1.0
        self.marker_pub.publish(MarkerArray(markers=markers))
        self.markers_published += 1
