"""Every request and response schema carries examples that its own validation accepts."""

from __future__ import annotations

import inspect

import pytest
from pydantic import BaseModel

from app import schemas, schemas_forecasts, schemas_locations, schemas_ops, schemas_residual

SCHEMAS = [
    cls
    for module in (schemas, schemas_forecasts, schemas_ops, schemas_locations, schemas_residual)
    for _, cls in inspect.getmembers(module, inspect.isclass)
    if issubclass(cls, BaseModel) and cls.__module__ == module.__name__
]


def test_every_schema_is_covered() -> None:
    assert len(SCHEMAS) >= 33


@pytest.mark.parametrize("schema", SCHEMAS, ids=lambda cls: cls.__name__)
def test_examples_validate(schema: type[BaseModel]) -> None:
    examples = schema.model_json_schema()["examples"]
    assert examples
    for example in examples:
        schema.model_validate(example)


def test_examples_reach_the_openapi_document() -> None:
    from app.main import create_app

    components = create_app().openapi()["components"]["schemas"]
    assert components["ForecastOut"]["examples"][0]["tail"] == "N100"
    assert components["InspectionIn"]["examples"][1]["detected"] is False
