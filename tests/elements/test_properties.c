/* Every property of every treestereo element refuses an out-of-range value: the param spec
 * validation changes it (numbers below the minimum or above the maximum when representable,
 * enum values no enum holds, flags bits no flag has), g_object_set warns and keeps the old
 * value, and every default lies within its own spec. The element list comes from the
 * registry, so an element added later is walked too. */
#include <gst/check/gstcheck.h>

#include <math.h>
#include <string.h>

/* Elements the plugin must hold at least (exgsegment joins when merged). */
static const gchar *const required_elements[] = {
  "treetestsrc", "stereorectify", "siftmatch", "stereodepth", "treemetrics", "treeoverlay",
  "spraycontrol", "treecamerasrc",
};

/* Fills @v (initialised to the spec's type) with a value just outside @p's range, below the
 * minimum when @low, else above the maximum. FALSE when no such value is representable in
 * the type (the range is the type's whole range, or the spec has no range). */
static gboolean
out_of_range (GParamSpec * p, GValue * v, gboolean low)
{
#define INT_CASE(SPEC, TYPE, TMIN, TMAX, SETTER)                               \
  if (G_IS_PARAM_SPEC_##SPEC (p)) {                                            \
    GParamSpec##TYPE *s = G_PARAM_SPEC_##SPEC (p);                              \
    if (low ? s->minimum == TMIN : s->maximum == TMAX)                          \
      return FALSE;                                                            \
    SETTER (v, low ? s->minimum - 1 : s->maximum + 1);                          \
    return TRUE;                                                               \
  }
  INT_CASE (INT, Int, G_MININT, G_MAXINT, g_value_set_int);
  INT_CASE (UINT, UInt, 0, G_MAXUINT, g_value_set_uint);
  INT_CASE (INT64, Int64, G_MININT64, G_MAXINT64, g_value_set_int64);
  INT_CASE (UINT64, UInt64, 0, G_MAXUINT64, g_value_set_uint64);
  INT_CASE (LONG, Long, G_MINLONG, G_MAXLONG, g_value_set_long);
  INT_CASE (ULONG, ULong, 0, G_MAXULONG, g_value_set_ulong);
  INT_CASE (CHAR, Char, G_MININT8, G_MAXINT8, g_value_set_schar);
  INT_CASE (UCHAR, UChar, 0, G_MAXUINT8, g_value_set_uchar);
#undef INT_CASE
  if (G_IS_PARAM_SPEC_DOUBLE (p)) {
    GParamSpecDouble *s = G_PARAM_SPEC_DOUBLE (p);
    gdouble x = low ? s->minimum - MAX (1.0, ABS (s->minimum) * 1e-6)
        : s->maximum + MAX (1.0, ABS (s->maximum) * 1e-6);
    if (!isfinite (x) || (low ? x >= s->minimum : x <= s->maximum))
      return FALSE;
    g_value_set_double (v, x);
    return TRUE;
  }
  if (G_IS_PARAM_SPEC_FLOAT (p)) {
    GParamSpecFloat *s = G_PARAM_SPEC_FLOAT (p);
    gfloat x = low ? s->minimum - MAX (1.0f, ABS (s->minimum) * 1e-5f)
        : s->maximum + MAX (1.0f, ABS (s->maximum) * 1e-5f);
    if (!isfinite (x) || (low ? x >= s->minimum : x <= s->maximum))
      return FALSE;
    g_value_set_float (v, x);
    return TRUE;
  }
  if (G_IS_PARAM_SPEC_ENUM (p)) {
    GEnumClass *k = G_PARAM_SPEC_ENUM (p)->enum_class;
    gint bad = low ? k->minimum - 1 : k->maximum + 1;
    /* an enum with gaps: any value between that names nothing would do too, the ends suffice */
    if (low && k->minimum == G_MININT)
      return FALSE;
    g_value_set_enum (v, bad);
    return TRUE;
  }
  if (G_IS_PARAM_SPEC_FLAGS (p)) {
    GFlagsClass *k = G_PARAM_SPEC_FLAGS (p)->flags_class;
    guint unused = ~k->mask;
    if (low || unused == 0)
      return FALSE;
    /* the lowest bit no flag uses */
    g_value_set_flags (v, unused & (~unused + 1));
    return TRUE;
  }
  return FALSE;
}

static gchar *
describe (const GValue * v)
{
  return g_strdup_value_contents (v);
}

/* Walks @name's properties; returns how many out-of-range values were tried. */
static guint
check_element (const gchar * name)
{
  GstElement *e = gst_element_factory_make (name, NULL);
  guint n_props = 0, tried = 0;
  GParamSpec **props;

  fail_unless (e != NULL, "cannot make %s", name);
  props = g_object_class_list_properties (G_OBJECT_GET_CLASS (e), &n_props);
  for (guint i = 0; i < n_props; i++) {
    GParamSpec *p = props[i];
    GValue def = G_VALUE_INIT;

    /* the default is within the spec */
    g_value_init (&def, p->value_type);
    g_param_value_set_default (p, &def);
    fail_if (g_param_value_validate (p, &def), "%s::%s: its default is out of its own range",
        name, p->name);
    g_value_unset (&def);

    if (!(p->flags & G_PARAM_WRITABLE) || (p->flags & G_PARAM_CONSTRUCT_ONLY))
      continue;
    for (int low = 0; low < 2; low++) {
      GValue bad = G_VALUE_INIT, before = G_VALUE_INIT, after = G_VALUE_INIT;
      gchar *bad_text, *before_text, *after_text;

      g_value_init (&bad, p->value_type);
      if (!out_of_range (p, &bad, low)) {
        g_value_unset (&bad);
        continue;
      }
      tried++;
      bad_text = describe (&bad);
      g_value_init (&before, p->value_type);
      g_value_init (&after, p->value_type);
      if (p->flags & G_PARAM_READABLE)
        g_object_get_property (G_OBJECT (e), p->name, &before);

      /* g_object_set validates against the spec, warns and leaves the property alone */
      ASSERT_WARNING (g_object_set_property (G_OBJECT (e), p->name, &bad));
      if (p->flags & G_PARAM_READABLE) {
        g_object_get_property (G_OBJECT (e), p->name, &after);
        before_text = describe (&before);
        after_text = describe (&after);
        fail_unless (g_param_values_cmp (p, &before, &after) == 0,
            "%s::%s: setting %s changed it from %s to %s", name, p->name, bad_text,
            before_text, after_text);
        g_free (before_text);
        g_free (after_text);
      }
      /* and validation pulls the value back into the range */
      fail_unless (g_param_value_validate (p, &bad), "%s::%s accepts %s", name, p->name,
          bad_text);
      if (g_getenv ("TREESTEREO_VERBOSE"))
        g_print ("%s::%s refuses %s\n", name, p->name, bad_text);
      g_free (bad_text);
      g_value_unset (&bad);
      g_value_unset (&before);
      g_value_unset (&after);
    }
  }
  g_free (props);
  gst_object_unref (e);
  return tried;
}

GST_START_TEST (test_every_property_rejects_out_of_range)
{
  GList *features = gst_registry_get_feature_list_by_plugin (gst_registry_get (), "treestereo");
  guint n_elements = 0, tried = 0;

  for (gsize i = 0; i < G_N_ELEMENTS (required_elements); i++) {
    GstElementFactory *f = gst_element_factory_find (required_elements[i]);
    fail_unless (f != NULL, "element %s is not in the plugin", required_elements[i]);
    gst_object_unref (f);
  }
  for (GList * l = features; l; l = l->next) {
    if (!GST_IS_ELEMENT_FACTORY (l->data))
      continue;
    tried += check_element (gst_plugin_feature_get_name (GST_PLUGIN_FEATURE (l->data)));
    n_elements++;
  }
  gst_plugin_feature_list_free (features);
  g_print ("%u elements, %u out-of-range values refused\n", n_elements, tried);
  fail_unless (n_elements >= G_N_ELEMENTS (required_elements));
  /* each element has at least one bounded numeric or enum property */
  fail_unless (tried >= n_elements, "only %u out-of-range values tried", tried);
}

GST_END_TEST;

static Suite *
properties_suite (void)
{
  Suite *s = suite_create ("properties");
  TCase *tc = tcase_create ("general");

  suite_add_tcase (s, tc);
  tcase_add_test (tc, test_every_property_rejects_out_of_range);
  return s;
}

GST_CHECK_MAIN (properties);
