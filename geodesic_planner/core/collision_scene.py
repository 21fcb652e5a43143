"""One scene object replaced in a collision model, without rebuilding the rest.

:meth:`.collision.CollisionModel.with_objects` builds a model from scratch: every object's bodies
(meshes read again) and every pair of bodies tested by the skip rules in Python, quadratic in the
bodies. A sensor's map (:mod:`.point_cloud`) is an object of up to a few hundred bodies (its octree
tiles), replaced with every cloud (:func:`.point_cloud.with_map`). :func:`with_object_replaced`
makes the same model by keeping the other bodies, their pairs and the pairs' reaches, and by
testing the new object's bodies only against the others: the skip rules of a pair of bodies depend
only on the two bodies, so the pairs kept are the ones the whole build would find, and the new
pairs are put in the build's order (by the first body's index, then the second's). The answer is
:meth:`with_objects` of the scene without ``object_id`` and with ``obj`` appended: equal bodies,
pairs, names, reaches and skip reasons (test/core/test_collision_scene.py compares every field and
distances and verdicts).

This is the model's own construction split out of :mod:`.collision` (one concept per module, and
that module is at its size limit): it reads and writes the model's private fields, and its test
fails when the model gains a field this module does not make.
"""
from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Any

import coal
import numpy as np

from .collision_bodies import Body, SceneObject, object_bodies, pair_key

if TYPE_CHECKING:
    from .collision import CollisionModel

__all__ = ['with_object_replaced']


def with_object_replaced(model: CollisionModel, object_id: str, obj: SceneObject | None) -> CollisionModel:
    """``model.with_objects`` of its scene without the object ``object_id`` (if there is one) and with
    ``obj`` appended (None: nothing appended), reusing every other body and pair.

    Raises:
        RequestError: as :meth:`~.collision.CollisionModel.with_objects` (``obj``'s name taken by
            another object or a link, too many objects).
    """
    from .collision import MAX_OBJECTS

    removing = any(o.id == object_id for o in model.objects)
    kept_objects = [o for o in model.objects if o.id != object_id]
    objects = kept_objects if obj is None else [*kept_objects, obj]
    if obj is not None and (obj.id in {o.id for o in kept_objects} or obj.id in model.body_names
                            or len(objects) > MAX_OBJECTS):
        return model.with_objects(objects)       # its errors
    m: Any = model                                # the fields below are the model's own (see the doc)
    bodies: tuple[Body, ...] = m._bodies
    n_robot = len(model.robot_bodies)
    keep = np.array([i < n_robot or not removing or b.name != object_id for i, b in enumerate(bodies)], dtype=bool)
    new: tuple[Body, ...] = () if obj is None else tuple(object_bodies(obj, model.robot,
                                                                        exact_meshes=model.exact_meshes))
    if any((b.kind, b.segment, b.name) != (new[0].kind, new[0].segment, new[0].name) for b in new):
        return model.with_objects(objects)       # not one rigid object: the whole build
    index = np.cumsum(keep) - 1                  # old body -> new body
    pair_kept = keep[m._ia] & keep[m._ib]
    ia, ib = index[m._ia[pair_kept]], index[m._ib[pair_kept]]
    names: list[tuple[str, str]] = [m._pair_names[p] for p in np.flatnonzero(pair_kept).tolist()]
    skipped = {k: why for k, why in m.skipped.items() if not removing or object_id not in k}
    others = [b for b, k in zip(bodies, keep) if k]
    if new:
        ia, ib, names = _new_pairs(m, others, new, ia, ib, names, skipped)
    out: Any = copy.copy(model)
    out.objects = tuple(objects)
    out._bodies = (*others, *new)
    out.skipped = skipped
    out._ia, out._ib = ia.astype(int), ib.astype(int)
    out._pair_names = names
    out.pairs = tuple(dict.fromkeys(names))
    out._segment = np.concatenate([m._segment[keep], np.array([b.segment for b in new], dtype=int)])
    out._offset = np.concatenate([m._offset[keep], np.array([b.offset for b in new]).reshape(-1, 4, 4)])
    out._center = np.concatenate([m._center[keep], np.array([b.center for b in new]).reshape(-1, 3)])
    out._radius = np.concatenate([m._radius[keep], np.array([b.radius for b in new], dtype=float)])
    prims = [(g.halfLength, g.radius) if isinstance(g, coal.Capsule) else (0.0, g.radius)
             if isinstance(g, coal.Sphere) else (np.nan, np.nan) for g in (b.geometry for b in new)]
    out._half = np.concatenate([m._half[keep], np.array([h for h, _ in prims], dtype=float)])
    out._prim_radius = np.concatenate([m._prim_radius[keep], np.array([r for _, r in prims], dtype=float)])
    out._relative_reach = out._pair_reaches()
    out._distance_fns = {}
    out._request, out._result = coal.DistanceRequest(), coal.DistanceResult()
    out._analytic = np.isfinite(out._half[out._ia]) & np.isfinite(out._half[out._ib])
    return out


def _new_pairs(m: Any,  # noqa: ANN401 - the model, private fields
               others: list[Body], new: tuple[Body, ...], ia: np.ndarray, ib: np.ndarray,
               names: list[tuple[str, str]], skipped: dict[tuple[str, str], str]
               ) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]]]:
    """The pairs with the new bodies (after ``others``; one name, kind and segment, so the skip rules
    answer alike for all of them) merged into the kept ones in the build's order; ``skipped`` updated."""
    n, name = len(others), new[0].name
    why = [m._skip(b, new[0]) for b in others]
    first = np.flatnonzero([not w for w in why])
    inner = m._skip(new[0], new[1]) if len(new) > 1 else None
    add_a, add_b = [np.repeat(first, len(new))], [np.tile(np.arange(n, n + len(new)), len(first))]
    if inner == '':
        lo, hi = np.triu_indices(len(new), 1)
        add_a.append(lo + n)
        add_b.append(hi + n)
    new_a, new_b = np.concatenate(add_a).astype(int), np.concatenate(add_b).astype(int)
    new_names = [pair_key(others[i].name, name) if i < n else (name, name) for i in new_a.tolist()]
    for b, w in zip(others, why):
        if w:
            skipped.setdefault(pair_key(b.name, name), w)
    if inner:
        skipped.setdefault((name, name), inner)
    for key in set(new_names):
        skipped.pop(key, None)
    ia, ib = np.concatenate([ia, new_a]), np.concatenate([ib, new_b])
    order = np.lexsort((ib, ia))
    joined = names + new_names
    return ia[order], ib[order], [joined[k] for k in order.tolist()]
