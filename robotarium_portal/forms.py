"""The pages' forms: sign-up (the guide's fields) and the experiment (the guide's "Define Your Experiment!")."""
from django import forms
from django.conf import settings
from django.contrib.auth import get_user_model, password_validation

from robotarium_portal.files import name_problem
from robotarium_portal.models import Experiment, Profile


class SignUpForm(forms.Form):
    email = forms.EmailField(help_text="Your real address: the confirmation link and your experiments' news go there.")
    password = forms.CharField(widget=forms.PasswordInput, strip=False)
    confirmation = forms.CharField(label="Password confirmation", widget=forms.PasswordInput, strip=False)
    name = forms.CharField(max_length=150)
    city = forms.CharField(max_length=100)
    state = forms.CharField(max_length=100)
    institute = forms.CharField(max_length=200)
    reason = forms.CharField(label="Why do you want to use the Robotarium?", max_length=2000, widget=forms.Textarea)

    existing_user = None   # an account with this address exists: the page answers as for a new one (no enumeration)

    def clean_email(self):
        email = self.cleaned_data["email"].strip().lower()
        self.existing_user = get_user_model().objects.filter(username=email).first()
        return email

    def clean(self):
        data = super().clean()
        if data.get("password") and data.get("password") != data.get("confirmation"):
            self.add_error("confirmation", "The two passwords differ.")
        elif data.get("password"):
            user = get_user_model()(username=data.get("email", ""), email=data.get("email", ""))
            try:
                password_validation.validate_password(data["password"], user)
            except forms.ValidationError as error:
                self.add_error("password", error)
        return data

    def save(self):
        data = self.cleaned_data
        user = get_user_model().objects.create_user(username=data["email"], email=data["email"],
                                                    password=data["password"])
        Profile.objects.create(user=user, name=data["name"], city=data["city"], state=data["state"],
                               institute=data["institute"], reason=data["reason"])
        return user


class MultipleFileInput(forms.ClearableFileInput):
    allow_multiple_selected = True


class MultipleFileField(forms.FileField):
    """Several files in one input (Django's documented pattern)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("widget", MultipleFileInput())
        super().__init__(*args, **kwargs)

    def clean(self, data, initial=None):
        single = super().clean
        if isinstance(data, (list, tuple)):
            return [single(d, initial) for d in data]
        return [single(data, initial)] if data else []


class ExperimentForm(forms.ModelForm):
    """Title, description, duration, robots; files to add (or remove), and which one is the main file."""
    upload = MultipleFileField(label="Add files", required=False,
                               help_text="Your own files only (not the Robotarium's): the main script, the modules "
                                         "it imports, the data files it reads.")
    main_file = forms.CharField(required=False, max_length=100,
                                help_text="The file that is run. Left empty: the only .py file.")
    remove = forms.MultipleChoiceField(required=False, widget=forms.CheckboxSelectMultiple)

    class Meta:
        model = Experiment
        fields = ["title", "description", "estimated_duration", "number_of_robots"]
        widgets = {"description": forms.Textarea(attrs={"rows": 4})}
        help_texts = {"estimated_duration": "Seconds; the run is stopped at 900 s (15 minutes) whatever you write.",
                      "number_of_robots": "Exactly as many as your script asks for."}

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        existing = self.instance.file_names() if self.instance.pk else []
        self.fields["remove"].choices = [(n, n) for n in existing]
        self.fields["estimated_duration"].widget.attrs.update(min=1, max=900)
        self.fields["number_of_robots"].widget.attrs.update(min=1, max=50)

    def clean_estimated_duration(self):
        value = self.cleaned_data["estimated_duration"]
        if not 1 <= value <= 900:
            raise forms.ValidationError("Between 1 and 900 seconds (a slot is 15 minutes).")
        return value

    def clean_number_of_robots(self):
        value = self.cleaned_data["number_of_robots"]
        if not 1 <= value <= 50:
            raise forms.ValidationError("Between 1 and 50 robots.")
        return value

    def clean_upload(self):
        uploads = self.cleaned_data.get("upload") or []
        problems = [name_problem(u.name) for u in uploads if name_problem(u.name)]
        too_big = [u.name for u in uploads if u.size > settings.PORTAL_MAX_FILE_BYTES]
        if problems:
            raise forms.ValidationError(problems)
        if too_big:
            raise forms.ValidationError("Too large (at most %d MB a file): %s"
                                        % (settings.PORTAL_MAX_FILE_BYTES // (1024 * 1024), ", ".join(too_big)))
        names = [u.name for u in uploads]
        if len(set(names)) != len(names):
            raise forms.ValidationError("Two uploaded files have the same name.")
        return uploads

    def clean(self):
        data = super().clean()
        existing = set(self.fields["remove"].choices and [c[0] for c in self.fields["remove"].choices])
        names = (existing - set(data.get("remove") or [])) | {u.name for u in data.get("upload") or []}
        if len(names) > settings.PORTAL_MAX_FILES:
            self.add_error("upload", "Too many files: %d; an experiment has at most %d."
                           % (len(names), settings.PORTAL_MAX_FILES))
        # The edit page's radio buttons name an existing file; its text box (main_file_new) a new one.
        main = (self.data.get("main_file_new") or data.get("main_file") or "").strip()
        if not main:
            scripts = sorted(n for n in names if n.endswith(".py"))
            main = scripts[0] if len(scripts) == 1 else ""
        if main and main not in names:
            self.add_error("main_file", "%r is not one of the experiment's files (%s)."
                           % (main, ", ".join(sorted(names)) or "none yet"))
        elif main and not main.endswith(".py"):
            self.add_error("main_file", "The main file must be a Python script (.py).")
        data["main_file"] = main
        data["file_names"] = names
        return data
