//! The window, compiled from `viewer/ui/app.slint`.

slint::slint! {
    export { App, ObjectRow } from "../ui/app.slint";
}
