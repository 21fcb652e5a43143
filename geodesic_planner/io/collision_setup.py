"""A collision model from files: the URDF's geometry, an SRDF, the package directories, a scene YAML.

``package://PKG/...`` is looked up in the given directories (``DIR/PKG/...``), then in the ament
index: the ``share`` directory of every prefix on ``AMENT_PREFIX_PATH``, where ament packages
install their meshes.
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

from ..core.collision import CollisionModel
from ..core.errors import RequestError, quoted
from ..core.kinematics import Chain
from ..core.robots import read_urdf_file, urdf_text


def package_dirs(given: Sequence[str] = ()) -> list[str]:
    """The directories searched for ``package://`` URIs: ``given``, then the ament index's."""
    ament = [os.path.join(p, 'share') for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    return [str(d) for d in given] + [d for d in ament if os.path.isdir(d)]


def read_srdf(path: str) -> str:
    """The text of an SRDF file (bounded like a URDF).

    Raises:
        RequestError: missing, unreadable, too large or not UTF-8 (the message names ``srdf``).
    """
    return read_urdf_file(path, param='srdf', kind='SRDF')


def collision_model(robot: Chain, urdf: str | None, *, srdf: str = '', packages: Sequence[str] = (),
                    padding: float, link_radius: float, exact_meshes: bool = False,
                    scene: str = '') -> CollisionModel:
    """The collision model of ``robot`` in the scene of a YAML file.

    Args:
        robot: the chain.
        urdf: its URDF text (None for a preset: capsules along the links).
        srdf: SRDF file path ('' : none).
        packages: directories holding packages for ``package://`` (the ament index is added).
        padding, link_radius: m.
        exact_meshes: check triangles instead of convex hulls.
        scene: scene YAML path ('' : no objects).
    Raises:
        GeodesicPlannerError: a file that cannot be read, a mesh not found, a bad value.
    """
    dirs = package_dirs(packages)
    model = CollisionModel.for_robot(robot, urdf, package_dirs=dirs,
                                     srdf=read_srdf(srdf) if srdf.strip() else None, padding=padding,
                                     exact_meshes=exact_meshes, link_radius=link_radius)
    if scene.strip():
        from .scene import load_scene
        try:
            objects = load_scene(scene, package_dirs=dirs)
        except OSError as err:
            raise RequestError(f'scene {quoted(scene)}: {err.strerror or err}') from err
        model = model.with_objects(objects)
    return model


#: The parameters a collision model is built from (besides the robot's).
PARAMETERS = ('collision_padding', 'link_radius', 'exact_meshes', 'srdf', 'package_dirs', 'scene')


def collision_for_parameters(values: Mapping[str, Any], robot: Chain, robot_key: tuple,
                             previous: CollisionModel | None, previous_key: tuple
                             ) -> tuple[CollisionModel | None, tuple]:
    """The collision model for the planner's parameter values (None when ``collision_check`` is
    false) and its key (``robot_key``, the key of the robot's parameters, plus :data:`PARAMETERS`);
    ``previous`` is reused while the key is unchanged, so that a scene changed at run time stays.

    Raises:
        GeodesicPlannerError: a file that cannot be read, a mesh not found, a bad value.
    """
    if not values['collision_check']:
        return None, ()
    key = robot_key + tuple(str(values[k]) for k in PARAMETERS)
    if previous is not None and previous_key == key:
        return previous, key
    urdf = urdf_text(str(values['robot']), str(values['robot_description']))
    model = collision_model(
        robot, urdf, srdf=str(values['srdf']), packages=list(values['package_dirs'] or ()),
        padding=float(values['collision_padding']), link_radius=float(values['link_radius']),
        exact_meshes=bool(values['exact_meshes']), scene=str(values['scene']))
    return model, key
