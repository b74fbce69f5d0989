/* The elements' properties, declared once in a table. Each row gives the property's spec (name,
 * nick, blurb, range, default, flags) and where its value lives in the element's settings; one
 * set_property and one get_property serve every element and take the lock that guards the
 * settings (the element's own mutex, or the object lock). The id of a property is its row's
 * number (from 1), so rows go in the order gst-inspect lists them.
 *
 * In class_init (the table itself may go when class_init returns; the specs keep the rows):
 *   auto props = PropertyTable<Settings>::in_state<GstTreeMetrics>(gobject_class);
 *   props.real("speed", "Speed", "...", 0.0, MAX_SPEED, DEFAULT_SPEED, TS_FIELD(speed));
 * A row whose value needs more than a copy (a conversion, a second field) gives its own setter
 * and getter on the settings (custom); one that must lock something else or act outside the
 * lock works on the object (on_object). */
#pragma once

#include <gst/gst.h>

#include <functional>
#include <mutex>
#include <string>
#include <type_traits>

namespace treestereo::gst {

/* The flags the elements' properties use. */
constexpr GParamFlags kRwPlaying = static_cast<GParamFlags>(
    G_PARAM_READWRITE | G_PARAM_STATIC_STRINGS | GST_PARAM_MUTABLE_PLAYING);
constexpr GParamFlags kRwReady =
    static_cast<GParamFlags>(G_PARAM_READWRITE | G_PARAM_STATIC_STRINGS | GST_PARAM_MUTABLE_READY);
constexpr GParamFlags kReadOnly =
    static_cast<GParamFlags>(G_PARAM_READABLE | G_PARAM_STATIC_STRINGS);

/* A settings member as a row's field: TS_FIELD(zone.near_mm) reads and writes s.zone.near_mm. */
#define TS_FIELD(member) [](auto &s_) -> auto & { return s_.member; }

/* What the generic set_property and get_property call; a row of any table. */
class PropertyRow {
public:
  virtual ~PropertyRow() = default;
  virtual void set(GObject *object, const GValue *value) const = 0;
  virtual void get(GObject *object, GValue *value) const = 0;
};

/* Installs @spec as property @id of @klass, served by @row (the spec owns it). */
void install_property_row(GObjectClass *klass, guint id, GParamSpec *spec, PropertyRow *row);
/* GObject's set_property and get_property for every table. */
void set_property_from_table(GObject *object, guint id, const GValue *value, GParamSpec *spec);
void get_property_from_table(GObject *object, guint id, GValue *value, GParamSpec *spec);

/* Holds @mutex, or the object lock of @object when @mutex is null. */
class SettingsLock {
public:
  SettingsLock(GObject *object, std::mutex *mutex);
  ~SettingsLock();
  SettingsLock(const SettingsLock &) = delete;
  SettingsLock &operator=(const SettingsLock &) = delete;

private:
  GObject *object_;
  std::mutex *mutex_;
};

/* A copy of the settings of an element that keeps them in self->state (settings, lock), taken
 * under their lock: what one buffer is processed with. */
template <typename Self> auto settings_snapshot(Self *self)
{
  std::lock_guard<std::mutex> g(self->state->lock);
  return self->state->settings;
}

template <typename S> class PropertyTable {
public:
  using Setter = std::function<void(S &, const GValue *)>;
  using Getter = std::function<void(const S &, GValue *)>;

  /* @settings finds the element's settings; @lock the mutex that guards them, or nullptr for
   * the object lock. Sets @klass' set_property and get_property. */
  PropertyTable(GObjectClass *klass, S &(*settings)(GObject *),
                std::mutex &(*lock)(GObject *) = nullptr)
      : klass_(klass), settings_(settings), lock_(lock)
  {
    klass->set_property = set_property_from_table;
    klass->get_property = get_property_from_table;
  }
  /* For an element that keeps its settings and their mutex in self->state (settings, lock). */
  template <typename Self> static PropertyTable in_state(GObjectClass *klass)
  {
    return PropertyTable(
        klass, [](GObject *o) -> S & { return reinterpret_cast<Self *>(o)->state->settings; },
        [](GObject *o) -> std::mutex & { return reinterpret_cast<Self *>(o)->state->lock; });
  }
  /* For an element that keeps its settings in the instance (self->settings) under the object
   * lock. */
  template <typename Self> static PropertyTable in_object(GObjectClass *klass)
  {
    return PropertyTable(klass,
                         [](GObject *o) -> S & { return reinterpret_cast<Self *>(o)->settings; });
  }
  PropertyTable(const PropertyTable &) = delete;
  PropertyTable &operator=(const PropertyTable &) = delete;

  /* Every row added from here on also runs @f on the settings after its value is set (e.g. to
   * mark that a worker must be rebuilt); nullptr stops it. */
  void after_set(std::function<void(S &)> f) { after_set_ = std::move(f); }

  template <typename F>
  void boolean(const char *name, const char *nick, const char *blurb, bool def, F field,
               GParamFlags flags = kRwPlaying)
  {
    copied(g_param_spec_boolean(name, nick, blurb, def, flags), field, g_value_get_boolean,
           g_value_set_boolean);
  }
  template <typename F>
  void integer(const char *name, const char *nick, const char *blurb, gint min, gint max, gint def,
               F field, GParamFlags flags = kRwPlaying)
  {
    copied(g_param_spec_int(name, nick, blurb, min, max, def, flags), field, g_value_get_int,
           g_value_set_int);
  }
  template <typename F>
  void uinteger(const char *name, const char *nick, const char *blurb, guint min, guint max,
                guint def, F field, GParamFlags flags = kRwPlaying)
  {
    copied(g_param_spec_uint(name, nick, blurb, min, max, def, flags), field, g_value_get_uint,
           g_value_set_uint);
  }
  template <typename F>
  void uint64(const char *name, const char *nick, const char *blurb, guint64 min, guint64 max,
              guint64 def, F field, GParamFlags flags = kRwPlaying)
  {
    copied(g_param_spec_uint64(name, nick, blurb, min, max, def, flags), field,
           g_value_get_uint64, g_value_set_uint64);
  }
  template <typename F>
  void real(const char *name, const char *nick, const char *blurb, double min, double max,
            double def, F field, GParamFlags flags = kRwPlaying)
  {
    copied(g_param_spec_double(name, nick, blurb, min, max, def, flags), field,
           g_value_get_double, g_value_set_double);
  }
  /* A std::string member; NULL sets it empty and an empty one reads as NULL. */
  template <typename F>
  void string(const char *name, const char *nick, const char *blurb, F field,
              GParamFlags flags = kRwPlaying)
  {
    custom(
        g_param_spec_string(name, nick, blurb, nullptr, flags),
        [field](S &s, const GValue *v) {
          const gchar *str = g_value_get_string(v);
          field(s) = str ? str : "";
        },
        [field](const S &s, GValue *v) {
          const std::string &str = field(s);
          g_value_set_string(v, str.empty() ? nullptr : str.c_str());
        });
  }
  /* An enum member of any type whose values are the GEnum's. */
  template <typename F>
  void enumeration(const char *name, const char *nick, const char *blurb, GType type, gint def,
                   F field, GParamFlags flags = kRwPlaying)
  {
    custom(
        g_param_spec_enum(name, nick, blurb, type, def, flags),
        [field](S &s, const GValue *v) {
          using T = std::remove_reference_t<decltype(field(s))>;
          field(s) = static_cast<T>(g_value_get_enum(v));
        },
        [field](const S &s, GValue *v) { g_value_set_enum(v, static_cast<gint>(field(s))); });
  }
  /* Any spec, with its own setter and getter on the settings (called under the lock). */
  void custom(GParamSpec *spec, Setter set, Getter get)
  {
    if (after_set_)
      set = [set, then = after_set_](S &s, const GValue *v) {
        set(s, v);
        then(s);
      };
    add(spec, new SettingsRow(settings_, lock_, std::move(set), std::move(get)));
  }
  /* Any spec, with a setter and getter on the object, called without a lock: for a value kept
   * elsewhere than the settings or one that acts outside the lock. @set may be null for a
   * read-only property. */
  void on_object(GParamSpec *spec, std::function<void(GObject *, const GValue *)> set,
                 std::function<void(GObject *, GValue *)> get)
  {
    add(spec, new ObjectRow(std::move(set), std::move(get)));
  }

private:
  /* A row whose value is the member as it is, through GValue's getter and setter of its type. */
  template <typename F, typename V>
  void copied(GParamSpec *spec, F field, V (*get)(const GValue *), void (*set)(GValue *, V))
  {
    custom(
        spec, [field, get](S &s, const GValue *v) { field(s) = get(v); },
        [field, set](const S &s, GValue *v) { set(v, field(s)); });
  }

  using Find = S &(*)(GObject *);
  using Lock = std::mutex &(*)(GObject *);
  class SettingsRow : public PropertyRow {
  public:
    SettingsRow(Find settings, Lock lock, Setter set, Getter get)
        : settings_(settings), lock_(lock), set_(std::move(set)), get_(std::move(get))
    {
    }
    void set(GObject *o, const GValue *v) const override
    {
      SettingsLock g(o, lock_ ? &lock_(o) : nullptr);
      set_(settings_(o), v);
    }
    void get(GObject *o, GValue *v) const override
    {
      SettingsLock g(o, lock_ ? &lock_(o) : nullptr);
      get_(settings_(o), v);
    }

  private:
    Find settings_;
    Lock lock_;
    Setter set_;
    Getter get_;
  };
  class ObjectRow : public PropertyRow {
  public:
    ObjectRow(std::function<void(GObject *, const GValue *)> set,
              std::function<void(GObject *, GValue *)> get)
        : set_(std::move(set)), get_(std::move(get))
    {
    }
    void set(GObject *o, const GValue *v) const override { set_(o, v); }
    void get(GObject *o, GValue *v) const override { get_(o, v); }

  private:
    std::function<void(GObject *, const GValue *)> set_;
    std::function<void(GObject *, GValue *)> get_;
  };

  void add(GParamSpec *spec, PropertyRow *row) { install_property_row(klass_, ++count_, spec, row); }

  GObjectClass *klass_;
  Find settings_;
  Lock lock_;
  std::function<void(S &)> after_set_;
  guint count_ = 0;
};

/* A finalize that deletes the instance's State (self->state) and chains up to @parent (the
 * G_DEFINE_TYPE parent class pointer). */
template <typename Self, gpointer *parent> void finalize_state(GObject *object)
{
  Self *self = reinterpret_cast<Self *>(object);
  delete self->state;
  self->state = nullptr;
  G_OBJECT_CLASS(*parent)->finalize(object);
}

} // namespace treestereo::gst
