"""The recording API in one import (former single module; the code lives beside it).

:mod:`.writer` (:class:`BagWriter`), :mod:`.reader` (:func:`read_bag`, :func:`bag_info`),
:mod:`.recover`, :mod:`.ros_types` (type names, message definitions, type hashes), :mod:`.qos`
and :mod:`.layout` (what the files look like and why).
"""
from .layout import ROSBAG2_VERSION, RUN_METADATA_NAME
from .qos import parse_qos_profiles, qos_profiles_yaml
from .reader import (BagError, BagInfo, TopicInfo, TruncatedBagWarning, bag_info,
                     read_bag)
from .recover import default_recover_destination, recover
from .ros_types import message_class, message_definition, type_description_hash, type_name
from .writer import BagWriter

__all__ = ["BagWriter", "BagError", "BagInfo", "TopicInfo", "TruncatedBagWarning", "bag_info",
           "read_bag", "recover", "default_recover_destination", "message_definition",
           "message_class", "type_name", "type_description_hash", "qos_profiles_yaml",
           "parse_qos_profiles", "RUN_METADATA_NAME", "ROSBAG2_VERSION"]
