"""Built-in binarizers of sbplan, registered through the sbplan entry-point group like any plugin."""

from sbplan.hookspecs import hookimpl


@hookimpl
def sbplan_register_stages(registry):
    from .background import BackgroundBinarizer
    from .local_mean import LocalMeanBinarizer
    from .otsu import OtsuBinarizer

    registry.add(BackgroundBinarizer)
    registry.add(LocalMeanBinarizer)
    registry.add(OtsuBinarizer)
