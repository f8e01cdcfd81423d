"""Files in and out: logged data (CSV, NPZ, MAT), motor files, atomic writes."""
