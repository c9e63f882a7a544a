#!/usr/bin/python3
# Makes pyephem_reference.csv, the independent oracle of tests/nav/solar_position_test.cpp: the sun's
# geometric topocentric altitude and azimuth (PyEphem / libastro with pressure = 0, i.e. no
# refraction), its apparent geocentric right ascension and declination of date and the Earth-Sun
# distance, for the GPS epoch and cases spread over 1990-2040: the seasons, both hemispheres, the
# poles, the equator, the date line, heights 0..12 km and the sun below the horizon.
#
# Needs Debian's python3-ephem (apt-get install python3-ephem); run: /usr/bin/python3 make_reference.py
# > pyephem_reference.csv. The C++ test only reads the CSV.
import math

import ephem

# utc (ephem.Date is UTC, taken as UT1), lat_deg, lon_deg (east positive), h_m, what it covers
CASES = [
    ("1980-01-06T00:00:00", 0.0, 0.0, 0, "the GPS epoch"),
    ("2003-10-17T19:30:30", 39.742476, -105.1786, 1830.14, "SPA's worked example site"),
    ("1990-01-01T12:00:00", 51.4779, -0.0015, 0, "Greenwich winter noon"),
    ("1990-06-21T03:30:00", 35.68, 139.69, 40, "Tokyo near summer noon"),
    ("1991-03-20T21:00:00", -33.87, 151.21, 50, "Sydney dawn"),
    ("1992-10-13T00:00:00", 0.0, 0.0, 0, "equator midnight, sun below"),
    ("1993-12-21T18:00:00", -78.0, 166.67, 200, "78 S summer, midnight sun"),
    ("1995-07-04T16:00:00", 40.7, -74.0, 10000, "New York at 10 km"),
    ("1996-02-29T10:00:00", 0.0, 30.0, 0, "leap day on the equator"),
    ("1998-09-23T06:00:00", -1.3, 36.8, 1700, "Nairobi at the equinox"),
    ("1999-12-31T23:59:59", 70.0, 25.0, 0, "70 N polar night"),
    ("2000-01-01T12:00:00", 45.0, 0.0, 0, "J2000"),
    ("2001-06-21T22:20:00", 70.0, 25.0, 0, "70 N midnight sun at local midnight"),
    ("2003-05-15T14:00:00", 60.17, 24.94, 12000, "Helsinki at 12 km"),
    ("2004-08-12T05:00:00", -23.5, -46.6, 760, "Sao Paulo at night"),
    ("2005-11-03T12:00:00", 19.4, -99.1, 2240, "Mexico City before dawn"),
    ("2006-01-01T00:00:00", 89.9, 0.0, 0, "next to the north pole, winter"),
    ("2008-06-20T12:00:00", 23.44, 0.0, 0, "sun near the zenith"),
    ("2009-07-22T02:35:00", 30.9, 121.2, 0, "Shanghai, eclipse day"),
    ("2010-03-21T00:00:00", 0.0, 179.9, 0, "equator at the date line, noon"),
    ("2011-09-01T23:00:00", -17.7, -179.9, 0, "west of the date line, south"),
    ("2012-06-30T23:59:59", 52.0, 13.4, 0, "before the 2012 leap second"),
    ("2012-07-01T00:00:01", 52.0, 13.4, 0, "after the 2012 leap second"),
    ("2013-12-21T20:00:00", -78.0, -40.0, 3000, "78 S at 3 km"),
    ("2014-02-14T08:00:00", 64.1, -21.9, 0, "Reykjavik winter morning, below"),
    ("2015-04-01T15:30:00", 37.6, -122.4, 12000, "San Francisco at 12 km"),
    ("2016-10-31T09:00:00", -34.6, -58.4, 25, "Buenos Aires dawn"),
    ("2017-08-21T18:00:00", 36.0, -87.0, 150, "Tennessee, eclipse day"),
    ("2018-12-25T06:00:00", 1.35, 103.8, 15, "Singapore afternoon"),
    ("2019-05-01T03:00:00", 78.2, 15.6, 10, "Svalbard at night, sun up"),
    ("2020-06-20T21:44:00", 70.0, -150.0, 5000, "70 N, solstice, 5 km"),
    ("2021-01-15T14:00:00", -45.9, 170.5, 0, "New Zealand night"),
    ("2022-03-20T15:33:00", 0.0, -60.0, 0, "equator at the equinox instant"),
    ("2023-07-15T11:00:00", 48.1, 11.6, 8000, "Munich at 8 km"),
    ("2024-06-20T20:51:00", 45.0, -100.0, 500, "June solstice 2024"),
    ("2024-11-03T12:00:00", 51.5, 0.0, 0, "equation of time maximum"),
    ("2026-08-12T17:45:00", 42.0, -3.0, 600, "Spain, eclipse day, low sun"),
    ("2030-06-01T12:00:00", -70.0, 0.0, 0, "70 S polar night"),
    ("2033-09-22T00:00:00", 33.0, -179.9, 11000, "date line at 11 km"),
    ("2036-02-14T18:30:00", -55.0, -68.0, 0, "Cape Horn afternoon"),
    ("2039-12-21T12:00:00", 66.56, 0.0, 0, "polar circle, winter solstice noon"),
    ("2040-12-31T23:00:00", -89.9, 0.0, 2835, "next to the south pole, summer"),
]


def main():
    print("utc,lat_deg,lon_deg,h_m,alt_deg,az_deg,ra_deg,dec_deg,dist_au")
    sun = ephem.Sun()
    for utc, lat, lon, h, _ in CASES:
        obs = ephem.Observer()
        obs.date = ephem.Date(utc.replace("-", "/").replace("T", " "))
        obs.lat = math.radians(lat)
        obs.lon = math.radians(lon)
        obs.elevation = h
        obs.pressure = 0  # no refraction: the geometric direction
        sun.compute(obs)
        print("%s,%.6f,%.6f,%.2f,%.6f,%.6f,%.6f,%.6f,%.9f" % (
            utc, lat, lon, h, math.degrees(sun.alt), math.degrees(sun.az),
            math.degrees(sun.g_ra), math.degrees(sun.g_dec), sun.earth_distance))


if __name__ == "__main__":
    main()
