// A runtime source that goes through a forbidden door: check_doors.py must refuse this tree.
#include "sfrt/camera/status.h"
