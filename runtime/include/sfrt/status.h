// Status and Result<T>: how every sfrt function that can fail reports it (declared once, for
// every module, in sfrt/vocabulary/status.h).
//
// Error policy of the runtime: loading, verifying and planning check everything and return a
// Status whose message names the file, layer and field at fault (one line, no trailing newline).
// The per-frame path (Session::Run) checks only its arguments; it never throws and never
// allocates.
#pragma once

#include "sfrt/vocabulary/status.h"
