// Status and Result<T> for camera/: the one sfrt::Status (sfrt/vocabulary/status.h), under the
// names camera code has always used. Capture gives every error a specific ErrorKind (unplugged,
// busy, no USB bandwidth, watchdog, ...) and the errno of the failing call; file sources,
// calibration and preprocessing use Status::Error(message).
#pragma once

#include "sfrt/vocabulary/status.h"

namespace sfrt::camera {

using sfrt::ErrorKind;
using sfrt::ErrorKindName;
using sfrt::Result;
using sfrt::Status;

}  // namespace sfrt::camera
