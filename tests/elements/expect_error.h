/* Checks of the elements' error policy (gst/elements/common.hpp): the next ERROR or WARNING on a
 * bus, its domain, code and message, and a part of its debug string. C and C++; include after
 * gst/check/gstcheck.h. */
#pragma once

#include <gst/check/gstcheck.h>

#include <string.h>

/* Pops the next message of @type (GST_MESSAGE_ERROR or GST_MESSAGE_WARNING) from @bus within
 * @timeout and checks its domain and code, that its message is @message (@exact) or holds it,
 * and that its debug string holds @debug_part (NULL: not checked). */
static inline void
check_bus_message (GstBus * bus, GstMessageType type, GstClockTime timeout, GQuark domain,
    gint code, const gchar * message, gboolean exact, const gchar * debug_part)
{
  GstMessage *msg = gst_bus_timed_pop_filtered (bus, timeout, type);
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
  if (exact) {
    fail_unless_equals_string (err->message, message);
  } else {
    fail_unless (strstr (err->message, message) != NULL, "'%s' not in the message: %s",
        message, err->message);
  }
  if (debug_part)
    fail_unless (debug != NULL && strstr (debug, debug_part) != NULL,
        "'%s' not in the debug string: %s", debug_part, debug ? debug : "(none)");
  g_free (debug);
  g_error_free (err);
  gst_message_unref (msg);
}

/* The next ERROR or WARNING (@type) on @bus within 5 s: its domain and code, its message
 * @message exactly, @debug_part in its debug string (NULL: not checked). */
static inline void
expect_bus_error (GstBus * bus, GstMessageType type, GQuark domain, gint code,
    const gchar * message, const gchar * debug_part)
{
  check_bus_message (bus, type, 5 * GST_SECOND, domain, code, message, TRUE, debug_part);
}

/* The same within @timeout, for a message that is not all ours (a library's text around a
 * name): it has to hold @message_part. */
static inline void
expect_bus_error_naming (GstBus * bus, GstMessageType type, GstClockTime timeout,
    GQuark domain, gint code, const gchar * message_part, const gchar * debug_part)
{
  check_bus_message (bus, type, timeout, domain, code, message_part, FALSE, debug_part);
}
