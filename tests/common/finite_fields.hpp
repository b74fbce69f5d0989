/* Every number in an element message must be finite: the walk shared by the tests that read
 * element messages. structure_all_finite() needs GStreamer only (the soak is a plain program);
 * expect_structure_finite() is for gstcheck tests (include this after <gst/check/gstcheck.h>). */
#pragma once

#include <gst/gst.h>

#include <cmath>
#include <string>

/* TRUE when every number in @v, recursively through structures and arrays, is finite; else
 * FALSE with the path of the first bad one (e.g. "treemetrics:bands[2].depth") in @where. */
inline bool value_all_finite(const GValue *v, const std::string &path, std::string *where)
{
  const GType t = G_VALUE_TYPE(v);
  bool ok = true;
  if (t == G_TYPE_DOUBLE) {
    ok = std::isfinite(g_value_get_double(v));
  } else if (t == G_TYPE_FLOAT) {
    ok = std::isfinite(g_value_get_float(v));
  } else if (t == GST_TYPE_ARRAY || t == GST_TYPE_LIST) {
    const bool array = t == GST_TYPE_ARRAY;
    const guint n = array ? gst_value_array_get_size(v) : gst_value_list_get_size(v);
    for (guint k = 0; k < n; k++)
      if (!value_all_finite(array ? gst_value_array_get_value(v, k)
                                  : gst_value_list_get_value(v, k),
                            path + "[" + std::to_string(k) + "]", where))
        return false;
  } else if (t == GST_TYPE_STRUCTURE) {
    const GstStructure *s = gst_value_get_structure(v);
    for (gint k = 0; k < gst_structure_n_fields(s); k++) {
      const gchar *name = gst_structure_nth_field_name(s, k);
      if (!value_all_finite(gst_structure_get_value(s, name), path + "." + name, where))
        return false;
    }
  }
  if (!ok && where)
    *where = path;
  return ok;
}

inline bool structure_all_finite(const GstStructure *s, std::string *where)
{
  for (gint k = 0; k < gst_structure_n_fields(s); k++) {
    const gchar *name = gst_structure_nth_field_name(s, k);
    if (!value_all_finite(gst_structure_get_value(s, name),
                          std::string(gst_structure_get_name(s)) + ":" + name, where))
      return false;
  }
  return true;
}

#ifdef fail_unless
/* Fails the gstcheck test when any field of @s is NaN or inf, naming the structure and field. */
static inline void expect_structure_finite(const GstStructure *s)
{
  std::string where;
  fail_unless(structure_all_finite(s, &where), "%s is not finite", where.c_str());
}
#endif
