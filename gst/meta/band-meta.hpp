/* C++ only, not installed: one height band between lib/core's BandExtent (a frame's Band, a tree
 * record's band) and the metas' GstTreeStereoBand, for the elements and the tools that read the
 * metas. An absent band carries zeros in the meta. */
#pragma once

#include <gst/treestereo/treestereo-meta.h>

#include "treestereo/metrics.hpp"

namespace treestereo {

/* The band's eight values, field by field, between the two structs (either way). */
template <class To, class From> void copy_band_values(To &o, const From &b)
{
  o.present = b.present ? 1 : 0;
  o.top_m = b.top_m;
  o.bottom_m = b.bottom_m;
  o.left_m = b.left_m;
  o.right_m = b.right_m;
  o.width_m = b.width_m;
  o.depth_m = b.depth_m;
  o.fill = b.fill;
}

inline void band_to_meta(const BandExtent &b, GstTreeStereoBand &o)
{
  o = GstTreeStereoBand{};
  if (b.present) // an absent band's values mean nothing: 0
    copy_band_values(o, b);
}

inline BandExtent band_from_meta(const GstTreeStereoBand &b)
{
  BandExtent o;
  copy_band_values(o, b);
  return o;
}

} // namespace treestereo
