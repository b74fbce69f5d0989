/* Every element of the plugin, declared once for plugin.cpp. */
#pragma once

#include <gst/gst.h>

G_BEGIN_DECLS
GST_ELEMENT_REGISTER_DECLARE(stereorectify);
GST_ELEMENT_REGISTER_DECLARE(siftmatch);
GST_ELEMENT_REGISTER_DECLARE(treetestsrc);
GST_ELEMENT_REGISTER_DECLARE(stereodepth);
GST_ELEMENT_REGISTER_DECLARE(treemetrics);
GST_ELEMENT_REGISTER_DECLARE(treeoverlay);
GST_ELEMENT_REGISTER_DECLARE(exgsegment);
GST_ELEMENT_REGISTER_DECLARE(spraycontrol);
GST_ELEMENT_REGISTER_DECLARE(treecamerasrc);
G_END_DECLS
