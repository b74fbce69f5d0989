/* The treestereo plugin: registers every element. */
#ifdef HAVE_CONFIG_H
#include "config.h"
#endif

#include "elements.hpp"

static gboolean plugin_init(GstPlugin *plugin)
{
  gboolean ret = FALSE;
  ret |= GST_ELEMENT_REGISTER(stereorectify, plugin);
  ret |= GST_ELEMENT_REGISTER(siftmatch, plugin);
  ret |= GST_ELEMENT_REGISTER(treetestsrc, plugin);
  ret |= GST_ELEMENT_REGISTER(stereodepth, plugin);
  ret |= GST_ELEMENT_REGISTER(treemetrics, plugin);
  ret |= GST_ELEMENT_REGISTER(treeoverlay, plugin);
  ret |= GST_ELEMENT_REGISTER(exgsegment, plugin);
  ret |= GST_ELEMENT_REGISTER(spraycontrol, plugin);
  ret |= GST_ELEMENT_REGISTER(treecamerasrc, plugin);
  return ret;
}

GST_PLUGIN_DEFINE(GST_VERSION_MAJOR, GST_VERSION_MINOR, treestereo,
                  "Measure fruit trees with a stereo camera pair: rectification, vegetation "
                  "segmentation, SIFT stereo matching, depth and canopy metrics",
                  plugin_init, VERSION, GST_LICENSE, GST_PACKAGE_NAME, GST_PACKAGE_ORIGIN)
