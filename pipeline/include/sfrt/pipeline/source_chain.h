// Several recordings replayed one after another as one FrameSource: a folder of bags
// (`sfrt run --replay-bags`), each a unit of its own. A unit's windows carry its name as their
// sequence, so no window spans two units and each unit's outputs are named "<unit>_<frame>"
// (OutputStem). A unit's source is made and opened when the one before it ends (one open at a
// time); its frames must have the first unit's size (the pipeline sizes its buffers once), else
// the run ends with an error naming both. Drops and window-chain counts are summed over the
// units, bad frames listed with their unit, and summary.json's source lists each unit's own facts
// ("units": [{"sequence": name, ...FrameSource::ToJson of that unit}]).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sfrt/pipeline/pipeline.h"

namespace sfrt::pipeline {

struct SourceUnit {
  std::string name;                                    // the unit's sequence name
  std::function<std::unique_ptr<FrameSource>()> make;  // its source, not opened
};

// `description` is Describe()'s line, `kind` kind()'s word. Open() fails when `units` is empty.
std::unique_ptr<FrameSource> MakeSourceChain(std::vector<SourceUnit> units, std::string description,
                                             std::string kind);

}  // namespace sfrt::pipeline
