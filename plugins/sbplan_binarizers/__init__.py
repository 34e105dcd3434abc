"""Built-in binarizers of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .local_mean import LocalMeanBinarizer
    from .otsu import OtsuBinarizer

    registry.add(LocalMeanBinarizer)
    registry.add(OtsuBinarizer)
