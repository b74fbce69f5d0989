/* The generic side of the property tables (properties.hpp): rows reached through their specs. */
#include "properties.hpp"

namespace treestereo::gst {

static GQuark row_quark()
{
  static const GQuark q = g_quark_from_static_string("treestereo-property-row");
  return q;
}

void install_property_row(GObjectClass *klass, guint id, GParamSpec *spec, PropertyRow *row)
{
  g_param_spec_set_qdata_full(spec, row_quark(), row,
                              [](gpointer r) { delete static_cast<PropertyRow *>(r); });
  g_object_class_install_property(klass, id, spec);
}

static const PropertyRow *row_of(GParamSpec *spec)
{
  return static_cast<const PropertyRow *>(g_param_spec_get_qdata(spec, row_quark()));
}

void set_property_from_table(GObject *object, guint id, const GValue *value, GParamSpec *spec)
{
  if (const PropertyRow *row = row_of(spec))
    row->set(object, value);
  else
    G_OBJECT_WARN_INVALID_PROPERTY_ID(object, id, spec);
}

void get_property_from_table(GObject *object, guint id, GValue *value, GParamSpec *spec)
{
  if (const PropertyRow *row = row_of(spec))
    row->get(object, value);
  else
    G_OBJECT_WARN_INVALID_PROPERTY_ID(object, id, spec);
}

SettingsLock::SettingsLock(GObject *object, std::mutex *mutex) : object_(object), mutex_(mutex)
{
  if (mutex_)
    mutex_->lock();
  else
    GST_OBJECT_LOCK(object_);
}

SettingsLock::~SettingsLock()
{
  if (mutex_)
    mutex_->unlock();
  else
    GST_OBJECT_UNLOCK(object_);
}

} // namespace treestereo::gst
