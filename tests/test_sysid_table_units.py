"""`autopilot sysid --table` with a row of units under the header, as a spreadsheet has it. Found by a model audit:
it was refused as "data row 1, thrust_port_n: 'N' is not a number", where the trial CSV and the mission read it.
Now it is skipped when its units are the columns', and refused naming the column when one is not."""

from __future__ import annotations

import pytest

from autopilot.schema import ConfigError
from autopilot.sysid.table import read_table_csv

HEADER = "name;thrust_port_n;thrust_stbd_n;yaw_rate_rad_s;speed_m_s\n"
ROWS = "A;20;20;0;1,2\nB;30;30;0;1,5\nC;20;10;0,1;1,1\nD;10;20;-0,1;1,0\n"  # a European Excel's decimal commas


def test_a_units_row_of_the_columns_units_is_skipped(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text(HEADER + ";[N];N;rad/s;m/s\n" + ROWS, encoding="utf-8-sig")
    rows = read_table_csv(path)
    assert [r.name for r in rows] == ["A", "B", "C", "D"] and rows[0].speed_m_s == 1.2


def test_a_units_row_with_another_unit_is_refused_naming_the_column(tmp_path):
    path = tmp_path / "table.csv"
    path.write_text(HEADER + "units;N;N;deg/s;m/s\n" + ROWS, encoding="utf-8")
    with pytest.raises(ConfigError, match=r"gives yaw_rate_rad_s in 'deg/s'; the table reads yaw_rate_rad_s in rad/s"):
        read_table_csv(path)
