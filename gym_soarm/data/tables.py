"""The arrow tables of a dataset's metadata that the writer builds by hand.

pyarrow is imported by the caller (an optional dependency) and handed in as ``pa``.
"""

from __future__ import annotations

import json
from typing import Any


def tasks_table(pa: Any, tasks: dict[str, int]) -> Any:
    """``meta/tasks.parquet``'s table of ``tasks`` (sentence -> index), with the index
    column "task" as pandas writes it, so ``pandas.read_parquet`` returns the table
    indexed by the task sentence as LeRobot expects."""
    rows = sorted(tasks.items(), key=lambda item: item[1])
    pandas_metadata = {
        "index_columns": ["task"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {
                "name": "task",
                "field_name": "task",
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": None,
            },
        ],
        "creator": {"library": "pyarrow", "version": pa.__version__},
        "pandas_version": "2.2.0",
    }
    schema = pa.schema(
        [pa.field("task_index", pa.int64()), pa.field("task", pa.string())],
        metadata={"pandas": json.dumps(pandas_metadata)},
    )
    return pa.Table.from_arrays(
        [pa.array([i for _, i in rows], pa.int64()), pa.array([t for t, _ in rows])],
        schema=schema,
    )


def arrow_type(pa: Any, value: Any) -> Any:
    """The arrow type of an episodes-table value: int, float, str or nested lists of them."""
    if isinstance(value, bool):
        return pa.bool_()
    if isinstance(value, int):
        return pa.int64()
    if isinstance(value, float):
        return pa.float64()
    if isinstance(value, str):
        return pa.string()
    return pa.list_(arrow_type(pa, value[0]))
