/* Test helper: an element with properties set from "name=value name=value" before a harness
 * starts it (a harness plays its element at once). */
#ifndef TREESTEREO_TEST_ELEMENT_PROPS_H
#define TREESTEREO_TEST_ELEMENT_PROPS_H

#include <gst/gst.h>

static inline GstElement *
element_with_props (const char *factory, const char *props)
{
  GstElement *e = gst_element_factory_make (factory, NULL);
  if (e && props) {
    gchar **kv = g_strsplit (props, " ", -1);
    for (gchar ** p = kv; *p; p++) {
      gchar **nv = g_strsplit (*p, "=", 2);
      if (nv[0] && nv[1])
        gst_util_set_object_arg (G_OBJECT (e), nv[0], nv[1]);
      g_strfreev (nv);
    }
    g_strfreev (kv);
  }
  return e;
}

#endif
