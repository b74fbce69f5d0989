/* Checks shared by the gstcheck tests that read element messages: every number in a message
 * structure must be finite. Include after <gst/check/gstcheck.h> (it uses fail_unless). */
#pragma once

#include <cmath>
#include <string>

/* Fails when any number in @v (recursively through structures and arrays) is NaN or inf. */
static inline void expect_finite(const GValue *v, const std::string &where)
{
  const GType t = G_VALUE_TYPE(v);
  if (t == G_TYPE_DOUBLE) {
    fail_unless(std::isfinite(g_value_get_double(v)), "%s is %g", where.c_str(),
                g_value_get_double(v));
  } else if (t == G_TYPE_FLOAT) {
    fail_unless(std::isfinite(g_value_get_float(v)), "%s is %g", where.c_str(),
                (double) g_value_get_float(v));
  } else if (t == GST_TYPE_ARRAY || t == GST_TYPE_LIST) {
    const guint n = t == GST_TYPE_ARRAY ? gst_value_array_get_size(v) : gst_value_list_get_size(v);
    for (guint k = 0; k < n; k++)
      expect_finite(t == GST_TYPE_ARRAY ? gst_value_array_get_value(v, k)
                                        : gst_value_list_get_value(v, k),
                    where + "[" + std::to_string(k) + "]");
  } else if (t == GST_TYPE_STRUCTURE) {
    const GstStructure *s = gst_value_get_structure(v);
    for (gint k = 0; k < gst_structure_n_fields(s); k++) {
      const gchar *name = gst_structure_nth_field_name(s, k);
      expect_finite(gst_structure_get_value(s, name), where + "." + name);
    }
  }
}

/* Fails when any field of @s is NaN or inf, naming the structure and the field. */
static inline void expect_structure_finite(const GstStructure *s)
{
  for (gint k = 0; k < gst_structure_n_fields(s); k++) {
    const gchar *name = gst_structure_nth_field_name(s, k);
    expect_finite(gst_structure_get_value(s, name),
                  std::string(gst_structure_get_name(s)) + ":" + name);
  }
}
