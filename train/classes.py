"""The detector's classes: SeaDronesSee's five, in its category order.

Class index k is SeaDronesSee category id k + 1 (``mgmot detect`` writes
``category_id = k + 1``; the runtime maps a model's class *names* onto these
ids, so a model with another order or other spellings still lands right).
Torch-free, so that the data loaders can be tested without PyTorch.
"""

CLASS_NAMES = ("swimmer", "boat", "jetski", "life_saving_appliances", "buoy")

# Category names seen in SeaDronesSee, the simulator and common exports, mapped
# onto the class index. Names not listed here (e.g. SeaDronesSee's "ignored")
# are not objects to learn.
CATEGORY_MAP = {
    "swimmer": 0,
    "swimmer with life jacket": 0,
    "person": 0,
    "boat": 1,
    "jetski": 2,
    "life_saving_appliances": 3,
    "life_saving_appliance": 3,
    "lifebuoy": 3,
    "life ring": 3,
    "buoy": 4,
}
