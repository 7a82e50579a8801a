"""The compensation export's options shared by ``fit`` and ``simulate``: the formats, and the
controller settings (axis names and numbers, detection unit, value conventions) from the
command line over the machine file's ``[export]`` table
(:mod:`diffguide.studies.exports.settings`). Nothing heavy is imported until a command runs,
so ``--help`` stays fast."""

#: ``--format`` choices; the same as :data:`diffguide.studies.exports.FORMATS` (tested)
FORMATS = ("csv", "isg", "isg-cross", "siemens-cec", "heidenhain", "fanuc")

#: ``--format`` help
FORMAT_HELP = (
    "format of --export-compensation: csv (errors and σ, µm/µrad), isg (ISG/TwinCAT CSV X EXX "
    "... ECX, mm and rad, errors, + FILE.lis lines x/y/z, chain, workpiece_axes and "
    "FILE.startup.lis), isg-cross (ISG cross compensation lists FILE.Y.lis, FILE.Z.lis; needs "
    "--axis-side and --isg-axis-numbers), siemens-cec (SINUMERIK CEC $AN_CEC tables EYX->Y, "
    "EZX->Z with the activation data; needs --axis-side), heidenhain (EXPERIMENTAL: TNC .COM "
    "with AXISPOS + X/Y/Z columns and a .CMA; no angles), fanuc (EXPERIMENTAL: pitch of X for "
    "parameters 3620-3624, a setting sheet; no straightness); docs: compensation-exports")
#: ``--axis-side`` help
AXIS_SIDE_HELP = (
    "side of the kinematic chain of the compensating axes, which sets the sign of the EYX/EZX "
    "tables: tool, workpiece (Y and Z alike) or Y=workpiece,Z=tool (X carries the workpiece)")

#: ``{setting: (metavar, help)}``; the option of each is in
#: :data:`~diffguide.studies.exports.settings.SETTINGS` (``--cec-axis-names`` ...)
OPTIONS = {
    "cec_axis_names": (
        "X=N,Y=N,Z=N",
        "siemens-cec: the SINUMERIK machine axis names of X, Y, Z (MD10000; identifiers, any "
        "of the three; default X=AX1,Y=AX2,Z=AX3; machine file: [export] cec_axis_names)"),
    "fanuc_detection_unit": (
        "UNIT",
        "fanuc: the axis' detection unit, IS-A (0.01 mm), IS-B (0.001 mm, the default), IS-C "
        "(0.0001 mm), IS-D, IS-E, or a length in mm (least command increment / CMR); machine "
        "file: [export] fanuc_detection_unit"),
    "isg_axis_numbers": (
        "X=N,Y=N,Z=N",
        "isg, isg-cross: the ISG logical axis numbers of X, Y, Z (P-VOLC-00001..3, kopf.achs_nr; "
        "no default: isg writes a line to fill in, isg-cross refuses); machine file: [export] "
        "isg_axis_numbers"),
    "isg_max_records": (
        "N",
        "isg: vol_comp[0].max_records of the start-up lines (default: the table's number of "
        "records; raise it for other files of the same compensation); machine file: [export] "
        "isg_max_records"),
    "heidenhain_values": (
        "compensation|error",
        "heidenhain: whether a .COM value is the compensation the TNC adds (default) or the "
        "error it subtracts: UNCONFIRMED from the documentation, stated in the note; machine "
        "file: [export] heidenhain_values"),
    "isg_cross_values": (
        "compensation|error",
        "isg-cross: the same for the cross compensation lists (default compensation; "
        "UNCONFIRMED, stated in the header); machine file: [export] isg_cross_values"),
}


def add_controller_options(p) -> None:
    """The controller settings as options of parser ``p`` (default: the machine file's)."""
    for key, (metavar, help_) in OPTIONS.items():
        p.add_argument("--" + key.replace("_", "-"), dest="export_" + key, default=None,
                       metavar=metavar, help=help_)
