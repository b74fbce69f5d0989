#include "treestereo/record_json.hpp"

#include "treestereo/json.hpp"

#include <sstream>

namespace treestereo {

JsonWriter &write_band(JsonWriter &w, const BandExtent &b)
{
  w.begin_object().field("present", b.present);
  if (b.present)
    w.field("top_m", b.top_m)
        .field("bottom_m", b.bottom_m)
        .field("left_m", b.left_m)
        .field("right_m", b.right_m)
        .field("width_m", b.width_m)
        .field("depth_m", b.depth_m)
        .field("fill", b.fill);
  return w.end_object();
}

std::string to_json(const TreeRecord &r)
{
  std::ostringstream s;
  JsonWriter w(s);
  w.begin_object()
      .field("id", r.id)
      .field("mode", canopy_mode_name(r.mode))
      .field("complete", r.complete)
      .field("position_m", r.position_m)
      .field("start_m", r.start_m)
      .field("end_m", r.end_m)
      .field("start_seen", r.start_seen)
      .field("end_seen", r.end_seen);
  if (r.has_depth)
    w.field("distance_m", r.distance_m);
  if (r.has_height)
    w.field("height_m", r.height_m);
  if (r.has_width)
    w.field("width_m", r.width_m);
  if (r.has_depth) {
    w.field("thickness_m", r.thickness_m);
    w.key("bands").begin_array();
    for (const BandExtent &b : r.bands)
      write_band(w, b);
    w.end_array();
  }
  w.field("frames", r.frames).field("frames_seen", r.frames_seen);
  if (r.has_depth)
    w.field("confidence", r.confidence);
  if (r.has_spacing)
    w.field("spacing_m", r.spacing_m).field("gap_m", r.gap_m);
  w.field("lost", r.lost).end_object();
  return s.str();
}

} // namespace treestereo
