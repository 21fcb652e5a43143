"""The planner node's scene at run time: services to set, remove and list collision objects, and
the scene as a MarkerArray for RViz.

- ``~/set_collision_object`` (SetCollisionObject): add an object, or replace the one of that id;
- ``~/remove_collision_object`` (RemoveCollisionObject): by id, or every object (empty id);
- ``~/list_collision_objects`` (ListCollisionObjects);
- ``~/scene_markers`` (visualization_msgs/MarkerArray, reliable, transient local): republished
  after every change.

A change builds a new collision model (the robot's bodies are reused) and swaps it into the
node's configuration in one step, so a plan checks against the scene before or after a change,
never half of one.
"""
from __future__ import annotations

from collections.abc import Callable
from geodesic_planner_interfaces.srv import ListCollisionObjects, RemoveCollisionObject, SetCollisionObject
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from visualization_msgs.msg import MarkerArray

from ..core.collision import CollisionModel
from ..core.errors import GeodesicPlannerError, quoted
from ..io.collision_setup import package_dirs
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

    def publish_markers(self) -> None:
        """Publish the current scene (an empty MarkerArray clears RViz's)."""
        model = self._current()
        objects = model.objects if model is not None else ()
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
                return model.with_objects([])
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
        response.objects = [scene_to_collision_object(o) for o in (model.objects if model else ())]
        return response
