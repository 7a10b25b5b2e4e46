// Stands in for camera/'s header in the tree check_doors.py must refuse.
#pragma once
