"""One value for a one-value query parameter.  FastAPI reads `?action=a&action=b` of a parameter
that takes one value as its last value and answers 200 (issue 42's fuzzing found it): a client
that sent two filters is answered for one of them without being told.  `one_value_each`, a
dependency of every router after its key check (app.main), refuses such a request with a 422
naming the parameter, on every route, once a missing or wrong key has had its 401 (and a key
without the route's role its 403, checked here as the route's own check would); a
parameter a route declares list-valued stays repeatable, and one it does not declare is ignored,
as any unknown parameter is."""

from __future__ import annotations

import types
from collections import Counter
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Annotated, Any, Union, get_args, get_origin

from fastapi import Request
from fastapi.dependencies.models import Dependant
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import BaseModel

from app.auth import allowed
from app.services.audit import Actor

if TYPE_CHECKING:
    from fastapi._compat import ModelField


async def one_value_each(request: Request) -> None:  # async: no I/O, no request thread
    """Raise RequestValidationError (a 422 naming each parameter, in the order sent) where a
    query parameter the route declares with one value is given more than once."""
    keys = [key for key, _ in request.query_params.multi_items()]
    if len(keys) == len(set(keys)):  # the common case: no name repeated, nothing to look up
        return
    route = request.scope.get("route")
    if not isinstance(route, APIRoute):
        return
    one_value = _one_value_names(route)
    errors = [
        {
            "type": "one_value",
            "loc": ("query", name),
            "msg": f"{name}: given {times} times; it takes one value",
            "input": request.query_params.getlist(name),
        }
        for name, times in Counter(keys).items()
        if times > 1 and name in one_value
    ]
    if errors:
        actor = getattr(request.state, "actor", None)
        if isinstance(actor, Actor):  # a route's own role check runs after this one
            for role in _roles(route.dependant):
                allowed(actor, role)
        raise RequestValidationError(errors)


def _roles(dependant: Dependant) -> Iterator[str]:
    """The roles the route's key checks (app.auth.require) ask for."""
    role = getattr(dependant.call, "required_role", None)
    if isinstance(role, str):
        yield role
    for dependency in dependant.dependencies:
        yield from _roles(dependency)


def _one_value_names(route: APIRoute) -> set[str]:
    """The names (aliases) of the route's query parameters, its dependencies' included and a
    parameter model's fields each one, that take one value."""
    names = set()
    for field in _query_fields(route.dependant):
        annotation = field.field_info.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            declared = annotation.model_fields.items()
            names |= {
                info.alias or name for name, info in declared if not _is_list(info.annotation)
            }
        elif not _is_list(annotation):
            names.add(field.alias)
    return names


def _query_fields(dependant: Dependant) -> Iterator[ModelField]:
    yield from dependant.query_params
    for dependency in dependant.dependencies:
        yield from _query_fields(dependency)


def _is_list(annotation: Any) -> bool:
    """A list-like type (list[str], tuple[int, ...], list[str] | None): FastAPI gathers every
    value of such a query parameter."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _is_list(get_args(annotation)[0])
    if origin is Union or origin is types.UnionType:
        return any(_is_list(arg) for arg in get_args(annotation))
    return isinstance(origin, type) and issubclass(origin, (list, tuple, set, frozenset, Sequence))
