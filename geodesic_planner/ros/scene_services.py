"""The planner node's scene at run time: services to set, remove and list collision objects, and
the scene as a MarkerArray for RViz.

- ``~/set_collision_object`` (SetCollisionObject): add an object, or replace the one of that id;
- ``~/remove_collision_object`` (RemoveCollisionObject): by id, or every object (empty id);
- ``~/list_collision_objects`` (ListCollisionObjects); a sensor's map (an occupancy octree of
  its point clouds, :mod:`~geodesic_planner.ros.sensor_maps`) is listed under its topic with a BOX
  primitive around its occupied voxels and, in ``mesh_resource``, a line ``octree: P points in V
  voxels of R m from a cloud of N points (...), A s old`` (the message has no description field);
  the maps are the sensors': set and remove refuse their names, and removing every object (empty
  id) keeps them;
- ``~/scene_markers`` (visualization_msgs/MarkerArray, reliable, transient local): republished
  after every change.

A change builds a new collision model (the robot's bodies are reused) and swaps it into the
node's configuration in one step, so a plan checks against the scene before or after a change,
never half of one.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from geodesic_planner_interfaces.msg import CollisionObject
from geodesic_planner_interfaces.srv import ListCollisionObjects, RemoveCollisionObject, SetCollisionObject
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from shape_msgs.msg import SolidPrimitive
from visualization_msgs.msg import MarkerArray

from ..core.collision import CollisionModel, SceneObject
from ..core.errors import GeodesicPlannerError, quoted
from ..io.collision_setup import package_dirs
from .conversions import matrix_to_pose
from .scene_msgs import collision_object_to_scene, scene_markers, scene_to_collision_object

#: change(model) -> new model, applied under the node's configuration lock; returns the new model.
Update = Callable[[Callable[[CollisionModel], CollisionModel]], CollisionModel]


class SceneServices:
    """The scene services and markers of a planner node.

    Args:
        node: the planner node.
        update: applies a change to the current collision model (raises GeodesicPlannerError when
            there is none: collision_check off, or no robot model yet).
        current: the current collision model, or None.
        packages: the package directories for ``package://`` mesh URIs.
        frame_id: the base frame, for the markers.
    """

    def __init__(self, node: Node, update: Update, current: Callable[[], CollisionModel | None],
                 packages: Callable[[], list[str]], frame_id: Callable[[], str]) -> None:
        self._node = node
        self._update = update
        self._current = current
        self._packages = packages
        self._frame_id = frame_id
        self.marker_pub = node.create_publisher(
            MarkerArray, '~/scene_markers',
            QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.set_srv = node.create_service(SetCollisionObject, '~/set_collision_object', self._on_set)
        self.remove_srv = node.create_service(RemoveCollisionObject, '~/remove_collision_object',
                                              self._on_remove)
        self.list_srv = node.create_service(ListCollisionObjects, '~/list_collision_objects', self._on_list)
        #: the sensors' maps (ids reserved, their lines for the list), set by the node when it has sensors
        self.maps: Any = None

    def _reserved(self) -> frozenset[str]:
        return self.maps.ids() if self.maps is not None else frozenset()

    def publish_markers(self) -> None:
        """Publish the current scene (an empty MarkerArray clears RViz's)."""
        model = self._current()
        objects = tuple(o for o in model.objects if o.shape.kind != 'octree') if model is not None else ()
        poses = model.body_poses(model.robot.home) if model is not None else None
        stamp = self._node.get_clock().now().to_msg()
        self.marker_pub.publish(scene_markers(objects, poses, self._frame_id(), stamp))

    def _change(self, what: str, change: Callable[[CollisionModel], CollisionModel]) -> tuple[bool, str]:
        try:
            model = self._update(change)
        except GeodesicPlannerError as err:
            self._node.get_logger().warning(f'{what}: refused: {err}')
            return False, str(err)
        except Exception as err:  # noqa: BLE001 - boundary: answer and keep serving
            return False, f'internal error: {type(err).__name__}: {err}'
        self._node.get_logger().info(f'{what}; scene: {len(model.objects)} objects '
                                     f'{[o.id for o in model.objects][:20]}')
        self.publish_markers()
        return True, ''

    def _on_set(self, request: SetCollisionObject.Request,
                response: SetCollisionObject.Response) -> SetCollisionObject.Response:
        try:
            obj = collision_object_to_scene(request.object, package_dirs(self._packages()))
        except GeodesicPlannerError as err:
            response.success, response.message = False, str(err)
            return response
        if obj.id in self._reserved():
            response.success = False
            response.message = f'collision object {quoted(obj.id)}: the name of a sensor\'s map (point_cloud_topics)'
            return response

        def change(model: CollisionModel) -> CollisionModel:
            kept = [o for o in model.objects if o.id != obj.id]
            return model.with_objects([*kept, obj])

        response.success, response.message = self._change(f'collision object {quoted(obj.id)} set', change)
        return response

    def _on_remove(self, request: RemoveCollisionObject.Request,
                   response: RemoveCollisionObject.Response) -> RemoveCollisionObject.Response:
        name = request.id

        def change(model: CollisionModel) -> CollisionModel:
            if not name:
                return model.with_objects([o for o in model.objects if o.id in self._reserved()])
            if name in self._reserved():
                raise GeodesicPlannerError(f'{quoted(name)} is a sensor\'s map: each cloud replaces it '
                                           '(point_cloud_topics)')
            if all(o.id != name for o in model.objects):
                raise GeodesicPlannerError(f'no collision object {quoted(name)} '
                                           f'(objects: {[o.id for o in model.objects][:20]})')
            return model.with_objects([o for o in model.objects if o.id != name])

        what = f'collision object {quoted(name)} removed' if name else 'every collision object removed'
        response.success, response.message = self._change(what, change)
        return response

    def _on_list(self, request: ListCollisionObjects.Request,
                 response: ListCollisionObjects.Response) -> ListCollisionObjects.Response:
        model = self._current()
        response.objects = [self._listed(o) for o in (model.objects if model else ())]
        listed = {o.id for o in response.objects}
        for name in sorted(self._reserved() - listed):       # a sensor without a map (yet)
            response.objects.append(CollisionObject(id=name, mesh_resource=self.maps.describe(name)))
        return response

    def _listed(self, obj: SceneObject) -> CollisionObject:
        """The message of an object; a map as a box around its voxels, with its line."""
        if obj.shape.kind != 'octree':
            return scene_to_collision_object(obj)
        c = np.asarray(obj.shape.vertices, dtype=float)
        res = float(obj.shape.dimensions[0])
        lo, hi = c.min(axis=0) - 0.5 * res, c.max(axis=0) + 0.5 * res
        pose = np.array(obj.pose, dtype=float)
        pose[:3, 3] = pose[:3, :3] @ (0.5 * (lo + hi)) + pose[:3, 3]
        msg = CollisionObject(id=obj.id, pose=matrix_to_pose(pose), mesh_resource=(
            self.maps.describe(obj.id) if self.maps is not None else f'octree: {len(c)} voxels of {res:g} m'))
        msg.primitive = SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[float(d) for d in hi - lo])
        return msg
