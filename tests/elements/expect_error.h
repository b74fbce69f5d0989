/* Checks of the elements' error policy (gst/elements/common.hpp): the next ERROR or WARNING on a
 * bus, its domain, code and message, and a part of its debug string. C and C++; include after
 * gst/check/gstcheck.h. */
#pragma once

#include <gst/check/gstcheck.h>

#include <string.h>

/* Pops the next message of @type (GST_MESSAGE_ERROR or GST_MESSAGE_WARNING) from @bus within
 * 5 s and checks its domain and code, that its message is @message (exactly) and that its debug
 * string holds @debug_part (NULL: not checked). */
static inline void
expect_bus_error (GstBus * bus, GstMessageType type, GQuark domain, gint code,
    const gchar * message, const gchar * debug_part)
{
  GstMessage *msg = gst_bus_timed_pop_filtered (bus, 5 * GST_SECOND, type);
  GError *err = NULL;
  gchar *debug = NULL;

  fail_unless (msg != NULL, "no %s on the bus", gst_message_type_get_name (type));
  if (type == GST_MESSAGE_WARNING)
    gst_message_parse_warning (msg, &err, &debug);
  else
    gst_message_parse_error (msg, &err, &debug);
  fail_unless (err->domain == domain && err->code == code, "%s %d instead of %s %d: %s",
      g_quark_to_string (err->domain), err->code, g_quark_to_string (domain), code,
      err->message);
  fail_unless_equals_string (err->message, message);
  if (debug_part)
    fail_unless (debug != NULL && strstr (debug, debug_part) != NULL,
        "'%s' not in the debug string: %s", debug_part, debug ? debug : "(none)");
  g_free (debug);
  g_error_free (err);
  gst_message_unref (msg);
}
