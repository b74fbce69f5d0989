// The row's tree records (treestereo/rowtrack.hpp) as JSON, for the tools' tree files.
#pragma once

#include "treestereo/json.hpp"
#include "treestereo/rowtrack.hpp"

#include <string>

namespace treestereo {

// One JSON line (no newline) with DESIGN.md's names: id, position_m, start_m, end_m,
// distance_m, height_m, width_m, thickness_m, bands, frames, confidence, plus complete,
// start_seen, end_seen, frames_seen, spacing_m, gap_m, lost, mode. A value the record lacks is
// absent, never null.
std::string to_json(const TreeRecord &record);

// One height band as a JSON object: present, and when present top_m, bottom_m, left_m, right_m,
// width_m, depth_m, fill (DESIGN.md's band names, in frames and records alike).
JsonWriter &write_band(JsonWriter &w, const BandExtent &band);

} // namespace treestereo
