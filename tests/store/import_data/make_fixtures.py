"""Write the small CSV fixtures of tests/store/test_import.py (run once; the files are committed).

Byte-exact: encodings, CRLF and separators are what the tests are about.
``bad_*`` files must be refused (exit 2, one line naming the file);
``good_*`` files must import.
"""

from pathlib import Path

HERE = Path(__file__).resolve().parent
GOOD = "time,position,force\r\n(s),(mm),(N)\r\n"
ROWS = ["0.00,0.000,0.001", "0.10,0.500,0.050", "0.20,1.000,0.100", "0.30,1.500,0.150"]


def crlf(*lines):
    return "".join(line + "\r\n" for line in lines)


FILES = {
    # semicolons, decimal commas, a cp1252 preamble (the degree sign before CRLF is no GBK), a units row
    "good_semicolon_decimal_comma.csv": (crlf(
        "Prüfung VHB 4910, Raumtemperatur 23°", "",
        "Zeit;Weg;Kraft;Temperatur", "s;mm;N;°C",
        "0,00;0,000;-0,0012;23,1", "0,50;1,250;0,1500;23,1", "1,00;2,500;0,2900;23,2",
        "1,50;3,750;0,4100;23,2"), "cp1252"),
    # trailing empty columns; units in the header names; LF only
    "good_trailing_empty_columns.csv": ("time (s),position [mm],force (N),,\n"
                                        "0.0,0.0,0.01,,\n0.1,0.4,0.02,,\n0.2,0.8,0.04,,\n0.3,1.2,0.05,,\n", "utf-8"),
    # tabs, quoted numbers, no header at all (columns by index, units by --units)
    "good_tab_no_header.tsv": (crlf('"0.0"\t"0.0"\t"0.1"', '"0.5"\t"2.0"\t"0.3"', '"1.0"\t"4.0"\t"0.5"'), "utf-8"),
    "bad_empty.csv": ("", "utf-8"),
    "bad_no_data.csv": (GOOD, "utf-8"),
    "bad_text_in_number.csv": (GOOD + crlf(ROWS[0], ROWS[1], "0.20,1.000,n/a", ROWS[3]), "utf-8"),
    "bad_time_backwards.csv": (GOOD + crlf(ROWS[0], ROWS[1], ROWS[2], "0.15,1.600,0.160", "0.40,2.000,0.200"),
                               "utf-8"),
    "bad_time_repeated.csv": (GOOD + crlf(ROWS[0], ROWS[1], "0.10,1.000,0.100", ROWS[3]), "utf-8"),
    "bad_unit_furlong.csv": ("time,position,force\r\n(s),(mm),(furlong)\r\n" + crlf(*ROWS), "utf-8"),
    "bad_unit_unknown.csv": ("time,position,force\r\n(s),(blorp),(N)\r\n" + crlf(*ROWS), "utf-8"),
    "bad_empty_field.csv": (GOOD + crlf(ROWS[0], ROWS[1], "0.20,1.000,", ROWS[3]), "utf-8"),
    "bad_nan_time.csv": (GOOD + crlf(ROWS[0], "nan,0.500,0.050", ROWS[2], ROWS[3]), "utf-8"),
    "bad_ragged_row.csv": (GOOD + crlf(ROWS[0], ROWS[1], "0.20,1.000,0.100,7", ROWS[3]), "utf-8"),
    "bad_stretch_below_one.csv": (GOOD + crlf(ROWS[0], "0.10,-5.000,0.050", ROWS[2], ROWS[3]), "utf-8"),
    "bad_one_row.csv": (GOOD + crlf(ROWS[0]), "utf-8"),
    "bad_no_units.csv": ("time,position,force\r\n" + crlf(*ROWS), "utf-8"),
    "bad_one_column.csv": (crlf("0.0", "0.1", "0.2"), "utf-8"),
}


def main():
    for name, (text, encoding) in FILES.items():
        (HERE / name).write_bytes(text.encode(encoding))


if __name__ == "__main__":
    main()
