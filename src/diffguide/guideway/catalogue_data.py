"""Runner blocks from manufacturers' catalogues: published values only, each block with its
source (read by :mod:`diffguide.guideway.catalogue`, which derives the model's internal geometry
from these figures). Units in the key names.

A block is named ``"<family> <size> <type>"``: the maker's series, the size class and the
maker's block-type code (here HIWIN's load class: HG and RG C = heavy load, H = super heavy
load; EG S = medium load, C = heavy load; the square and flange blocks of one load class share
C, C0 and rigidity).

- ``element``: ``"ball"`` or ``"roller"``.
- ``preload_classes``: ``(low, high)`` fractions of the dynamic capacity C, as published.
- ``rigidity_N_um``: the published rigidity per preload class in the family's
  ``rigidity_direction``; ``rigidity_load`` says at which load the catalogue gives it. Empty
  where the sources read publish no rigidity as numbers (HIWIN RG: the Technical Information
  shows a graph only): such a block is calibrated to the rigidity its user gives.
- ``C_N``: the dynamic capacity as published; for roller blocks HIWIN rates it for 100 km
  (C100; ball blocks: 50 km), and the preload classes are fractions of that C.
- dimensions (mm): ``block_height`` H (rail foot to block top), ``block_width`` W,
  ``body_length`` L1 (steel body, without end caps), ``block_length`` L (with end caps),
  ``bolt_pattern`` (along X, across Y), ``rail_width`` WR, ``rail_height`` HR.
"""

#: Where the figures come from: ``{key: {short, catalogue, edition, pages, url}}``.
SOURCES = {
    "hiwin-compact": {
        "short": "HIWIN Compact catalogue",
        "catalogue": "HIWIN Compact: Linear Guideways, Ballscrews, Linear Stages "
        "(HIWIN GmbH, Offenburg, www.hiwin.de)",
        "edition": "year not printed in the copy read",
        "pages": "p. 10 (Table 1.12 preload), p. 11 (Tables 1.13, 1.14 rigidity HG, EG), p. 18 "
        "(HG dimension table, HGH..CA / HGH..HA), p. 21 (sec. 1.1.13, EGH..SA / EGH..CA)",
        "url": "https://vdocuments.net/linear-guideways-ballscrews-positioning-systems-hiwin-p-007-c-dyn-28-p-z0-elastic.html",
    },
    "hiwin-technical-information": {
        "short": "HIWIN Technical Information G99TE20-1808",
        "catalogue": "HIWIN Linear Guideway Technical Information "
        "(HIWIN Technologies Corp., www.hiwin.tw)",
        "edition": "G99TE20-1808",
        "pages": "p. 26 (Table 2-1-12 preload classes, HG series); "
        "sec. 2-1-1 (contact at 45 degrees)",
        "url": "https://www.hiwin.tw",
    },
    "hiwin-technical-information-rg": {
        "short": "HIWIN Technical Information G99TE20-1808, RG series",
        "catalogue": "HIWIN Linear Guideway Technical Information "
        "(HIWIN Technologies Corp., www.hiwin.tw)",
        "edition": "G99TE20-1808",
        "pages": "p. 145 (sec. 2-9-1, rollers at a 45-degree contact angle), p. 150 (Table "
        "2-9-13 preload classes, RG series), p. 161 (sec. 2-9-13 (1) dimension table "
        "RGH-CA / RGH-HA, C (C100) and C0)",
        "url": "https://www.hiwin.tw",
    },
}

#: Per family: element, published contact angle (degrees), preload classes, rigidity basis.
FAMILIES = {
    "HIWIN-HG": {
        "element": "ball",
        "contact_angle_deg": 45.0,
        "source": "hiwin-technical-information",
        # Table 2-1-12 of the Technical Information; the Compact (Table 1.12) gives the same Z0
        # and ZA ranges and ZB as "above 0.1 C".
        "preload_classes": {"Z0": (0.0, 0.02), "ZA": (0.05, 0.07), "ZB": (0.1, 0.12)},
        "rigidity_direction": "radial",
        "rigidity_load": "not stated (deflection = load / rigidity, Compact formula 1.1)",
    },
    "HIWIN-EG": {
        "element": "ball",
        "contact_angle_deg": None,  # not found in the sources read
        "source": "hiwin-compact",
        # Compact Table 1.12, the EG ranges
        "preload_classes": {"Z0": (0.0, 0.02), "ZA": (0.03, 0.05), "ZB": (0.06, 0.08)},
        "rigidity_direction": "radial",
        "rigidity_load": "not stated (deflection = load / rigidity, Compact formula 1.1)",
    },
    "HIWIN-RG": {
        "element": "roller",
        "contact_angle_deg": 45.0,
        "source": "hiwin-technical-information-rg",
        # Table 2-9-13 of the Technical Information (RG series)
        "preload_classes": {"Z0": (0.02, 0.04), "ZA": (0.07, 0.09), "ZB": (0.12, 0.14)},
        "rigidity_direction": "radial",
        "rigidity_load": "none published as numbers in the source read (a graph only)",
    },
}

#: The blocks, user units (N, N/µm, mm).
BLOCKS = [
    {
        "family": "HIWIN-HG",
        "size": "25",
        "type": "C",
        "source": "hiwin-compact",
        "C_N": 26480.0,
        "C0_N": 56190.0,
        "rigidity_N_um": {"Z0": 520.0, "ZA": 630.0, "ZB": 730.0},
        "block_height_mm": 40.0,
        "block_width_mm": 48.0,
        "body_length_mm": 58.0,
        "block_length_mm": 84.0,
        "bolt_pattern_mm": (35.0, 35.0),
        "rail_width_mm": 23.0,
        "rail_height_mm": 22.0,
    },
    {
        "family": "HIWIN-HG",
        "size": "25",
        "type": "H",
        "source": "hiwin-compact",
        "C_N": 32750.0,
        "C0_N": 76000.0,
        "rigidity_N_um": {"Z0": 670.0, "ZA": 810.0, "ZB": 950.0},
        "block_height_mm": 40.0,
        "block_width_mm": 48.0,
        "body_length_mm": 78.6,
        "block_length_mm": 104.6,
        "bolt_pattern_mm": (50.0, 35.0),
        "rail_width_mm": 23.0,
        "rail_height_mm": 22.0,
    },
    {
        "family": "HIWIN-HG",
        "size": "35",
        "type": "C",
        "source": "hiwin-compact",
        "C_N": 49520.0,
        "C0_N": 102870.0,
        "rigidity_N_um": {"Z0": 680.0, "ZA": 830.0, "ZB": 980.0},
        "block_height_mm": 55.0,
        "block_width_mm": 70.0,
        "body_length_mm": 80.0,
        "block_length_mm": 112.4,
        "bolt_pattern_mm": (50.0, 50.0),
        "rail_width_mm": 34.0,
        "rail_height_mm": 29.0,
    },
    {
        "family": "HIWIN-HG",
        "size": "35",
        "type": "H",
        "source": "hiwin-compact",
        "C_N": 60210.0,
        "C0_N": 136310.0,
        "rigidity_N_um": {"Z0": 860.0, "ZA": 1060.0, "ZB": 1260.0},
        "block_height_mm": 55.0,
        "block_width_mm": 70.0,
        "body_length_mm": 105.8,
        "block_length_mm": 138.2,
        "bolt_pattern_mm": (72.0, 50.0),
        "rail_width_mm": 34.0,
        "rail_height_mm": 29.0,
    },
    # HIWIN Compact p. 11 Table 1.14 (rigidity EG) and p. 21 (EGH..SA / EGH..CA): S = medium
    # load (no bolt spacing C along X given), C = heavy load.
    {
        "family": "HIWIN-EG",
        "size": "25",
        "type": "S",
        "source": "hiwin-compact",
        "C_N": 11400.0,
        "C0_N": 19500.0,
        "rigidity_N_um": {"Z0": 200.0, "ZA": 240.0, "ZB": 270.0},
        "block_height_mm": 33.0,
        "block_width_mm": 48.0,
        "body_length_mm": 35.5,
        "block_length_mm": 61.1,
        "bolt_pattern_mm": None,
        "rail_width_mm": 23.0,
        "rail_height_mm": 18.0,
    },
    {
        "family": "HIWIN-EG",
        "size": "25",
        "type": "C",
        "source": "hiwin-compact",
        "C_N": 16270.0,
        "C0_N": 32400.0,
        "rigidity_N_um": {"Z0": 290.0, "ZA": 360.0, "ZB": 400.0},
        "block_height_mm": 33.0,
        "block_width_mm": 48.0,
        "body_length_mm": 59.0,
        "block_length_mm": 84.6,
        "bolt_pattern_mm": (35.0, 35.0),
        "rail_width_mm": 23.0,
        "rail_height_mm": 18.0,
    },
    # HIWIN Technical Information G99TE20-1808 p. 161 (RGH..CA / RGH..HA): no rigidity numbers
    # are published there, so ``rigidity_N_um`` is empty and the user gives the rigidity.
    {
        "family": "HIWIN-RG",
        "size": "25",
        "type": "C",
        "source": "hiwin-technical-information-rg",
        "C_N": 27700.0,
        "C0_N": 57100.0,
        "rigidity_N_um": {},
        "block_height_mm": 40.0,
        "block_width_mm": 48.0,
        "body_length_mm": 64.5,
        "block_length_mm": 97.9,
        "bolt_pattern_mm": (35.0, 35.0),
        "rail_width_mm": 23.0,
        "rail_height_mm": 23.6,
    },
    {
        "family": "HIWIN-RG",
        "size": "25",
        "type": "H",
        "source": "hiwin-technical-information-rg",
        "C_N": 33900.0,
        "C0_N": 73400.0,
        "rigidity_N_um": {},
        "block_height_mm": 40.0,
        "block_width_mm": 48.0,
        "body_length_mm": 81.0,
        "block_length_mm": 114.4,
        "bolt_pattern_mm": (50.0, 35.0),
        "rail_width_mm": 23.0,
        "rail_height_mm": 23.6,
    },
    {
        "family": "HIWIN-RG",
        "size": "35",
        "type": "C",
        "source": "hiwin-technical-information-rg",
        "C_N": 57900.0,
        "C0_N": 105200.0,
        "rigidity_N_um": {},
        "block_height_mm": 55.0,
        "block_width_mm": 70.0,
        "body_length_mm": 79.0,
        "block_length_mm": 124.0,
        "bolt_pattern_mm": (50.0, 50.0),
        "rail_width_mm": 34.0,
        "rail_height_mm": 30.2,
    },
    {
        "family": "HIWIN-RG",
        "size": "35",
        "type": "H",
        "source": "hiwin-technical-information-rg",
        "C_N": 73100.0,
        "C0_N": 142000.0,
        "rigidity_N_um": {},
        "block_height_mm": 55.0,
        "block_width_mm": 70.0,
        "body_length_mm": 106.5,
        "block_length_mm": 151.5,
        "bolt_pattern_mm": (72.0, 50.0),
        "rail_width_mm": 34.0,
        "rail_height_mm": 30.2,
    },
]
