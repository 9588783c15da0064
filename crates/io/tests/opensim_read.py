"""Reads a `.mot` and a `.trc` file with OpenSim 4.6 (the `opensim` package from PyPI) and prints
what it understood as one JSON line.

Usage: python opensim_read.py FILE.mot FILE.trc

The `.mot` goes through both of OpenSim's readers: the Storage class (what the GUI and the
analyses load motions with) and TimeSeriesTable (the STOFileAdapter). The `.trc` goes through
TimeSeriesTableVec3 (the TRCFileAdapter), as OpenSim's marker-based tools read it.
"""

import json
import math
import sys

import opensim


def main():
    mot, trc = sys.argv[1], sys.argv[2]
    storage = opensim.Storage(mot)
    table = opensim.TimeSeriesTable(mot)
    labels = list(table.getColumnLabels())
    times = list(table.getIndependentColumn())
    first_row = [table.getRowAtIndex(0)[i] for i in range(table.getNumColumns())]
    markers = opensim.TimeSeriesTableVec3(trc)
    row = markers.getRowAtIndex(0)
    # A missing sample reads as NaN, which JSON cannot hold: null instead.
    positions = {
        name: [v if math.isfinite(v) else None for v in (row[i][0], row[i][1], row[i][2])]
        for i, name in enumerate(markers.getColumnLabels())
    }
    print(
        json.dumps(
            {
                "mot": {
                    "storage_rows": storage.getSize(),
                    "storage_in_degrees": storage.isInDegrees(),
                    "storage_columns": storage.getColumnLabels().getSize(),
                    "rows": table.getNumRows(),
                    "labels": labels,
                    "times": [times[0], times[1], times[-1]],
                    "first_row": first_row,
                    "in_degrees": table.getTableMetaDataAsString("inDegrees"),
                },
                "trc": {
                    "rows": markers.getNumRows(),
                    "markers": markers.getNumColumns(),
                    "units": markers.getTableMetaDataAsString("Units"),
                    "rate": float(markers.getTableMetaDataAsString("DataRate")),
                    "first_frame": positions,
                },
            }
        )
    )


main()
